"""The effective grip depth as a fitted nuisance parameter of the diagnosis (docs/diagnosis.md).

A real bias-extension grip holds the fabric over a depth known to a few mm only; the free
length it leaves sets the shear the grip displacement imposes, so a wrong depth leaves a misfit
that a candidate effect could absorb (a false alarm). The depth is not a modulus (the mesh
changes with it, no tangent sensitivity), so it is profiled: for each candidate depth d the
plug-in option ``grip_depth`` of every experiment whose test has one is set to d, the baseline
is fitted, and the χ² of the fits are compared on the same data, the field rows outside the
deepest candidate's grips (x ≥ d_max and x ≤ length − d_max), so that every depth is judged on
the same n. The depth of least χ² is kept; the diagnosis then uses all rows outside its grips.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from mpi4py import MPI

from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.log import rank0
from fabricsurf.model.terms import Term

logger = logging.getLogger(__name__)

KEY = "grip_depth"


def has_grips(exp: Experiment) -> bool:
    """Whether the experiment's test declares a grip depth option (bias extension)."""
    return any(KEY in keys for keys in get_test(exp.test).keys.values())


def check_depths(exps: list[Experiment], depths: list[float], where: str) -> None:
    """Reject an empty list, negative or non-finite depths, depths the plug-in refuses (grips
    leaving less than half the specimen free) and data without a test that has grips."""
    if not depths or not all(math.isfinite(d) and d >= 0 for d in depths):
        raise ValueError(
            f"{where}: grip depths {list(depths)} must be one or more finite depths ≥ 0 mm"
        )
    gripped = [e for e in exps if has_grips(e)]
    if not gripped:
        raise ValueError(
            f"{where}: no experiment has grips of finite depth (tests "
            f"{sorted({e.test for e in exps})}); a grip depth needs a "
            "bias_extension experiment"
        )
    for e in gripped:
        get_test(e.test).check_specimen(
            with_depth(e, max(depths)).setup, f"{where}, experiment '{e.name}'"
        )


def with_depth(exp: Experiment, depth: float) -> Experiment:
    """The experiment with grips of ``depth`` mm (unchanged if its test has no grips)."""
    if not has_grips(exp):
        return exp
    return replace(exp, setup=replace(exp.setup, options=exp.setup.options | {KEY: float(depth)}))


def outside_grips(exp: Experiment, depth: float) -> Experiment:
    """The experiment without the field rows inside grips of ``depth`` mm."""
    if not has_grips(exp) or not exp.has_field:
        return exp
    keep = (exp.X[:, 0] >= depth) & (exp.X[:, 0] <= exp.length - depth)
    return replace(exp, field_step=exp.field_step[keep], X=exp.X[keep], u=exp.u[keep])


def grip_profile(
    exps: list[Experiment],
    depths: list[float],
    make_model: Callable[[], list[Term]],
    free_terms: list[str],
    h: float | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> dict:
    """χ² of the baseline fit at each grip depth on common data (module docstring), each depth
    logged at PROGRESS.

    ``make_model``: a fresh model (its terms at the starting moduli) for each depth;
    ``free_terms``: the terms whose moduli are fitted. Returns {"profile": [{"depth_mm",
    "chi2", "misfit", "n"}], "best_mm"}.
    """
    check_depths(exps, depths, "grip_depths")
    common = [outside_grips(e, max(depths)) for e in exps]
    rows = []
    for d in sorted(set(float(x) for x in depths)):
        with ForwardSet([with_depth(e, d) for e in common], make_model(), h=h, comm=comm) as fs:
            free = [i for i, (t, _) in enumerate(fs.params) if t.name in free_terms]
            res = fit(fs, free, space="linear")
        rows.append(
            {
                "depth_mm": d,
                "chi2": res.chi2,
                "misfit": res.misfit["combined"],
                "n": res.misfit["n"],
                "params": res.params(),
            }
        )
        rank0(
            logger,
            comm,
            f"[grip depth] {d:g} mm: misfit {rows[-1]['misfit']:.4g} "
            f"(chi2 {res.chi2:.5g} over {rows[-1]['n']} data)",
        )
    if len({q["n"] for q in rows}) > 1:
        raise RuntimeError(
            f"grip depth profile: the depths saw different data counts "
            f"{[q['n'] for q in rows]}; a point lies outside some mesh"
        )
    best = rows[int(np.argmin([q["chi2"] for q in rows]))]["depth_mm"]
    return {"profile": rows, "best_mm": best}
