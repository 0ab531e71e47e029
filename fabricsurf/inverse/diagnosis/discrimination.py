"""Which measurement would separate a tie? (docs/diagnosis.md, "Separating a tie")

For two tied candidates a (the verdict) and b (:mod:`~.ties`), each refitted model predicts a
few candidate experiments built from the data's first experiment: the same test at twice the
displacement, another fibre angle, a narrower specimen (bias tests), a picture-frame test with
clamped fibres (for a first-gradient effect), the field where the data gave forces only. Each
gets the data's noise levels and as many load steps and field points per step as the data, so
the candidates are compared at the same cost of measurement. At the refits' moduli the two
predictions differ by

    S₀ = Σ ((u_a − u_b)/s_u)² + Σ ((F_a − F_b)/s_F)²

but data of the new experiment would be fitted again, and a refit takes up the part of the
difference its moduli can reach: the separation is S = |P⊥ δ|², δ the difference in noise
units and P⊥ the projection off the sensitivities dr/dp of either refit's moduli on the new
experiment (linearised; the smaller of the two). Measured on the ±30° suggestion of
tests/test_diagnose_ties.py: S₀ overstated what a refit on the new data left by a factor of
about 3. If a is the truth, the new data give χ²_b − χ²_a with mean S and standard
deviation 2√S (:mod:`~.ties`), so the tie test's z is about √S/2: the experiment is expected
to separate the two when √S/2 exceeds the critical z of the tie rule, and reliably (98 %)
when it exceeds it by 2: S grows in proportion to the data, so ``data_factor`` =
(2(z_crit + 2))²/S says how many times the candidate's points, steps or 1/noise² it takes.
Candidates are ranked by S. The data's own test gets S from the refits' predictions (no run):
small, that is the tie; the region of the specimen where the two predictions differ most tells
where denser field data would help. Cost: two forward runs per candidate (with the tangent
sensitivities to the fitted moduli) at the diagnosis's mesh size.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from scipy import stats

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.experiment import Experiment, template
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.report import Diagnosis
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.forward import misfit as mf
from fabricsurf.inverse.forward.load_path import Prediction
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.model.terms import make_term

Z_CRIT = float(stats.norm.isf(0.5 * (1.0 - sg.LEVEL)))
"""The two-sided critical z of the tie rule at :data:`~.significance.LEVEL`."""
Z_POWER = Z_CRIT + 2.0
"""An expected z this large is above :data:`Z_CRIT` in 98 % of draws: ``data_factor`` is how
many times the candidate's data (points × steps, or 1/noise²) it takes to reach it, S ∝ data."""


@dataclass
class Candidate:
    """One experiment that might separate the tie: a key, what to do, the experiment."""

    key: str
    description: str
    exp: Experiment


@dataclass
class Design:
    """The data's own test (``as_measured``), the candidates ranked (``ranked``) and the
    difference maps (``maps``: title, experiment, |u_a − u_b|/s_u at its field rows, for the
    figure: the data's test and the best candidate)."""

    effects: list[str]
    as_measured: dict
    ranked: list[dict]
    maps: list[tuple[str, Experiment, np.ndarray]]

    def suggested(self) -> dict | None:
        """The candidate of largest separation (None if none could be run)."""
        return next((q for q in self.ranked if q.get("separation") is not None), None)

    def as_dict(self) -> dict:
        return {
            "effects": self.effects,
            "suggested": self.suggested(),
            "as_measured": self.as_measured,
            "candidates": self.ranked,
            "z_critical": Z_CRIT,
            "figure": "tie_difference_map.png",
        }


def _grid(length: float, width: float, n: int) -> np.ndarray:
    """About ``n`` points on a grid inside the specimen (5 % margins), square-ish cells."""
    if n == 0:
        return np.zeros((0, 2))
    nx = max(2, round(math.sqrt(n * length / width)))
    ny = max(2, round(n / nx))
    x = np.linspace(0.05 * length, 0.95 * length, nx)
    y = np.linspace(0.05 * width, 0.95 * width, ny)
    return np.array([(a, b) for a in x for b in y])


def _like(
    e0: Experiment,
    key: str,
    description: str,
    length: float,
    width: float,
    path: np.ndarray,
    angles,
    test: str | None = None,
    options: dict | None = None,
) -> Candidate:
    """A candidate with ``e0``'s noise, steps and points per step (module docstring); the
    field where ``e0`` has none only for the key "field_data" (on 50 points a step)."""
    n = (
        len(e0.field_step) // max(len(e0.steps), 1)
        if e0.has_field
        else 50
        if key == "field_data"
        else 0
    )
    exp = template(
        length,
        width,
        path,
        _grid(length, width, n),
        angles=angles,
        name=key,
        test=test or e0.test,
        options=dict(e0.setup.options) if options is None else options,
        force=e0.has_force,
    )
    s_u, s_F = mf.scales(e0)
    exp.noise_std = e0.noise_std or (s_u if e0.has_field else None)
    exp.force_noise_std = e0.force_noise_std or (s_F if e0.has_force else None)
    return Candidate(key, description, exp)


def candidates(e0: Experiment, first_gradient: bool = True) -> list[Candidate]:
    """The experiments tried, built from the data's first experiment (module docstring);
    the picture frame only if ``first_gradient`` (a tied effect of the first gradient: the
    frame's exact solution is a homogeneous shear, in which every second-gradient energy
    vanishes, so it cannot separate two of them)."""
    L, W, ang, path = e0.length, e0.width, e0.fibre_angles_deg, np.asarray(e0.path, float)
    out = [
        _like(
            e0,
            "larger_displacement",
            f"the same {e0.test} test to twice the displacement ({2 * path[-1]:.3g} mm)",
            L,
            W,
            2.0 * path,
            ang,
        )
    ]
    for v in get_test(e0.test).separating_variants(e0.setup, path, first_gradient):
        out.append(
            _like(e0, v.key, v.description, v.length, v.width, v.path, v.angles, v.test, v.options)
        )
    if not e0.has_field:
        out.append(
            _like(
                e0,
                "field_data",
                f"the same {e0.test} test with the displacement "
                "field measured (the data give forces only)",
                L,
                W,
                path,
                ang,
            )
        )
    return out


def separation(exp: Experiment, pa: Prediction, pb: Prediction) -> dict:
    """S of the module docstring at the refits' moduli, its field and force parts, S after
    either model's moduli are refitted to the other's prediction (linearised, the smaller of
    the two: what the new data would leave), the expected z and the data factor of that."""
    if exp.has_field and exp.noise_std is None:  # field where the data gave none: 1 % of |u|
        exp.noise_std = 0.01 * float(np.nanmax(np.linalg.norm(pa.u, axis=1)))
    ra, Ja = mf.residuals(exp, pa)
    rb, Jb = mf.residuals(exp, pb)
    delta = rb - ra
    n_force = len(exp.steps) if exp.has_force else 0
    force = float(delta[len(delta) - n_force :] @ delta[len(delta) - n_force :])
    S = float(delta @ delta)
    reach = "discrimination: a refit's reach"
    Sr = min(float(np.sum(la.off_span(J, delta, reach) ** 2)) for J in (Ja, Jb))
    return {
        "separation_fixed_moduli": S,
        "field": S - force,
        "force": force,
        "separation": Sr,
        "expected_z": 0.5 * math.sqrt(Sr),
        "separates": 0.5 * math.sqrt(Sr) > Z_CRIT,
        "data_factor": (2.0 * Z_POWER) ** 2 / Sr if Sr > 0 else math.inf,
    }


def _model(rf: FitResult) -> list:
    """Fresh terms at a refit's moduli (the diagnosis's term set, so no new form)."""
    return [make_term(t, **ps) for t, ps in rf.params().items()]


def _predict(c: Candidate, ra: FitResult, rb: FitResult, h: float, comm: MPI.Comm):
    model = _model(ra)
    with ForwardModel(c.exp, model, h=h, comm=comm) as fm:
        fm.set_values(ra.values)
        pa = fm.run(sens=ra.free)
        fm.set_values(rb.values)
        pb = fm.run(sens=rb.free)
    return pa, pb


def where_they_differ(exp: Experiment, du: np.ndarray, blocks: int = 3) -> dict:
    """The region (blocks × blocks over the specimen) with the largest Σ(Δu/s_u)²."""
    ix = np.minimum((exp.X[:, 0] / exp.length * blocks).astype(int), blocks - 1)
    iy = np.minimum((exp.X[:, 1] / exp.width * blocks).astype(int), blocks - 1)
    tot = np.bincount(iy * blocks + ix, weights=np.nan_to_num(du**2), minlength=blocks * blocks)
    k = int(np.argmax(tot))
    i, j = k % blocks, k // blocks
    return {
        "x_mm": [exp.length * i / blocks, exp.length * (i + 1) / blocks],
        "y_mm": [exp.width * j / blocks, exp.width * (j + 1) / blocks],
        "share_of_separation": float(tot[k] / max(tot.sum(), 1e-300)),
    }


def design(
    exps: list[Experiment],
    ra: FitResult,
    rb: FitResult,
    effects: list[str],
    h: float | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    keys: list[str] | None = None,
) -> Design:
    """Rank the candidate experiments (``keys``: a subset of them) by the separation of the
    refits ``ra`` and ``rb`` of the tied ``effects`` at the data's mesh size ``h`` (module
    docstring)."""
    e0 = exps[0]
    pa0 = ra.prediction[0] if isinstance(ra.prediction, list) else ra.prediction
    pb0 = rb.prediction[0] if isinstance(rb.prediction, list) else rb.prediction
    own = {"description": f"the data's own test ({e0.name})"} | separation(e0, pa0, pb0)
    maps = []
    if e0.has_field:
        du0 = np.linalg.norm(pa0.u - pb0.u, axis=1) / mf.scales(e0)[0]
        own["where_they_differ_most"] = where_they_differ(e0, du0)
        maps.append((f"as measured ({e0.name})", e0, du0))
    h = float(h or get_test(e0.test).default_h(e0.setup))
    rows, diff = [], {}
    for c in candidates(e0, any(make_term(n).order < 2 for n in effects)):
        if keys is not None and c.key not in keys:
            continue
        row = {
            "key": c.key,
            "description": c.description,
            "test": c.exp.test,
            "specimen_mm": [c.exp.length, c.exp.width],
            "fibre_angles_deg": list(c.exp.fibre_angles_deg),
            "path": [float(x) for x in c.exp.path],
        }
        try:
            pa, pb = _predict(c, ra, rb, h, comm)
        except (LoadStepError, ValueError) as e:
            rows.append(row | {"separation": None, "failed": str(e)})
            continue
        rows.append(row | separation(c.exp, pa, pb))
        diff[c.key] = (
            c.description,
            c.exp,
            np.linalg.norm(pa.u - pb.u, axis=1) / mf.scales(c.exp)[0],
        )
    rows.sort(key=lambda q: -1.0 if q["separation"] is None else -q["separation"])
    if rows and rows[0]["key"] in diff:
        maps.append(diff[rows[0]["key"]])
    return Design(list(effects), own, rows, maps)


def separate_tie(
    d: Diagnosis, exps: list[Experiment], h: float | None = None, comm: MPI.Comm = MPI.COMM_WORLD
) -> tuple[Diagnosis, Design | None]:
    """For a diagnosis ``d`` that ends in a tie: the experiments that would separate its first
    two members (:func:`design` of their refits, at the data's mesh size ``h``) and a copy of
    ``d`` that holds them as its ``separating_experiment``; ``d`` itself is left as it was.
    Without a tie: ``(d, None)``. The design's ``maps`` are the figure's
    (:func:`~fabricsurf.inverse.plots.figures.difference_map`, tie_difference_map.png)."""
    if not d.tied():
        return d, None
    a, b = d.tie.members[:2]
    des = design(exps, d.tie.refits[a], d.tie.refits[b], [a, b], h=h, comm=comm)
    return dataclasses.replace(d, separating_experiment=des.as_dict()), des
