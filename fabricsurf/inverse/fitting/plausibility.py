"""Moduli no fabric has: a fitted modulus that stands in for an effect the model lacks
(docs/diagnosis.md, "Moduli no fabric has").

A fit minimises the misfit whatever the moduli mean, so where the model lacks the mechanism the
data show, another term takes its work. In a bias test that is mostly the yarns: fitted soft
enough to stretch, fibre stretch carries elongation that the fabric gets by shearing. The rules,
on the fitted (free) yarn moduli, from one forward run at the fitted moduli (the last load step):

* **shear deficit** (a bias test whose data impose a shear angle γ_kin ≥ :data:`SHEAR_DEG`:
  the zone-C angle of a net whose yarns do not stretch at the largest grip displacement, Cao
  et al. 2008 eq. 13, generalised to ±θ): the model's largest shear angle falls short of γ_kin
  by more than :data:`DEFICIT` of it. With the grip displacement prescribed, the elongation the
  shear does not give comes from the yarns, so more than a tenth of the test's shear went into
  yarn stretch. Not the yarns' largest strain (reported with it): the continuum concentrates
  strain at the grips' corners whatever the yarns (docs/diagnosis.md has the measurements).
* **yarn strain** (other tests, where no kinematic angle is known): the yarns stretch by more
  than :data:`STRAIN_BOUND` (max |λ − 1|, |μ − 1| at the quadrature points) while the model
  shears by at least :data:`SHEAR_DEG`. Why 1 %: woven yarns have tensile stiffnesses of
  10³–10⁵ N/mm per unit width (glass, carbon, decrimping included) and a shear test loads them
  with about its force over its width, ~1 N/mm, so they stretch by 10⁻³ at most; the bound is
  ten times that, and a yarn strain ε lengthens a sheared zone as about 2ε rad of shear (±45°:
  √2·cos(π/4 − γ/2) ≈ 1 + γ/2): at 1 % the yarns carry a tenth of 10° of shear.
* **stated range**: a modulus outside the range the user states (``plausible``:
  {"term.param": (low, high)}; the command line's ``--plausible fibre_stretch.k_l=1000:1e5``).

The effect a modulus stands in for is the other term whose modulus correlates most with it in
the fit's covariance (the two share the work the data see); without a covariance, shear. A yarn
rule reports only when that correlation is at least :data:`CORRELATION` (or unknown): data that
determine the yarns' stiffness apart from the shear's (a displacement field) make their stretch
the fabric's own; a force curve that sees only their sum does not.
"""

from __future__ import annotations

import logging

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.evaluation import max_over_cells, quadrature_expression
from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.errors import InputError
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.forward import ranks
from fabricsurf.log import warn
from fabricsurf.model.terms import EFFECTS

logger = logging.getLogger(__name__)

STRAIN_BOUND = 0.01
"""The largest yarn strain a fitted model may show in a test that shears (module docstring)."""
DEFICIT = 0.1
"""The largest share of the data's shear angle the model may miss (module docstring)."""
SHEAR_DEG = 10.0
"""A test shears the fabric when its data's shear angle reaches this (deg)."""
CORRELATION = 0.8
"""A yarn modulus is a stand-in only when the fit trades it against another term's: their
moduli correlate by at least this much in the fit's covariance (module docstring)."""
FIBRE_MODULI = {"fibre_stretch.k_l": "max_strain_l", "fibre_stretch.k_m": "max_strain_m"}

ADVICE = (
    "fix it from a tensile test: the yarns' k_l, k_m in a --params file, held with "
    "`fabricsurf diagnose … --fixed fibre_stretch` (Python: diagnose(…, params=…, "
    "fixed=['fibre_stretch']); with --max-effects 0 that is a fit with the yarns held)",
    "hold the yarns inextensible: FibreStretch(inextensible=True) in Python (λ = μ = 1 "
    "exactly), or nearly so with --fixed fibre_stretch at k_l = k_m = 1e5 N/mm",
    "let the search look for what is missing: with the yarns held, `fabricsurf diagnose` "
    "ranks the effects the stretch took the place of (shear_locking, …) and searches beyond "
    "the vocabulary (--beyond-features)",
)


def parse_plausible(spec: str | dict | None) -> dict[str, tuple[float, float]]:
    """{"term.param": (low, high)} from "term.param=low:high[,…]" or a dict of pairs; each
    name and range checked (InputError naming the problem)."""
    if not spec:
        return {}
    items = spec.items() if isinstance(spec, dict) else []
    if isinstance(spec, str):
        items = []
        for part in (s.strip() for s in spec.split(",") if s.strip()):
            name, eq, rng = part.partition("=")
            lo, colon, hi = rng.partition(":")
            if not eq or not colon:
                raise InputError(
                    f"--plausible {spec}: '{part}' is not term.param=low:high "
                    "(e.g. fibre_stretch.k_l=1000:1e5)"
                )
            try:
                items.append((name.strip(), (float(lo), float(hi))))
            except ValueError:
                raise InputError(f"--plausible {spec}: '{rng}' is not two numbers") from None
    out = {}
    for name, (lo, hi) in items:
        term, _, p = name.partition(".")
        if term not in EFFECTS or p not in EFFECTS[term].parameters():
            raise InputError(
                f"--plausible: '{name}' is not a modulus (term.param, e.g. fibre_stretch.k_l)"
            )
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi):
            raise InputError(f"--plausible: {name}={lo:g}:{hi:g} must have 0 ≤ low < high")
        out[name] = (float(lo), float(hi))
    return out


def kinematic_shear_deg(exp) -> float | None:
    """The zone-C shear angle (deg) of an inextensible net at the largest grip displacement of
    a bias test at ±θ (Cao et al. 2008 eq. 13 for θ = 45°: cos φ = cos θ (1 + d/D), γ =
    2(θ − φ), D = L − W/tan θ); None beyond the lock (the net cannot follow the grip without
    stretching) and for other tests."""
    if exp.test != "bias_extension" or len(exp.path) == 0:
        return None
    a = [abs(np.radians(x)) % np.pi for x in exp.fibre_angles_deg]
    theta = min(x if x <= np.pi / 2 else np.pi - x for x in a)
    depth = float(exp.setup.options.get("grip_depth", 0.0))
    D = exp.length - 2 * depth - exp.width / np.tan(theta)
    if D <= 0:
        return None
    c = np.cos(theta) * (1.0 + float(np.max(exp.path)) / D)
    return None if c >= 1.0 else float(np.degrees(2.0 * (theta - np.arccos(c))))


def implied_strains(fm, values) -> list[dict] | None:
    """Per experiment at the moduli ``values``: the largest yarn strains |λ − 1|, |μ − 1| and
    |γ| (deg) of the model at the last load step (one forward run, no sensitivities; reduced
    over the ranks), and the data's shear angle. None when the run fails."""
    fm.set_values(values)
    try:
        fm.run(False)
    except LoadStepError:
        return None
    out = []
    for m in getattr(fm, "models", [fm]):
        rec = {"experiment": m.exp.name, "kinematic_shear_deg": kinematic_shear_deg(m.exp)}
        # rank 0 first on a rank-local mesh: it compiles, the others load (forward/ranks.py)
        got = ranks.rank0_first(m.comm, m.local, lambda m=m: _state_numbers(m.test.problem))
        for key, v in got.items():  # the same on every rank: maxima over the ranks
            if isinstance(v, dict):
                rec[key] = {n: float(m.comm.allreduce(x, op=MPI.MAX)) for n, x in v.items()}
            else:
                rec[key] = float(m.comm.allreduce(v, op=MPI.MAX))
        out.append(rec)
    return out


def _state_numbers(problem) -> dict:
    """The largest |λ − 1|, |μ − 1|, |γ| (deg) at the quadrature points and each term's share
    of the strain energy, reduced over the mesh's own ranks; {} without an energy form."""
    energy = getattr(problem, "energy", None)
    if energy is None:
        return {}
    kin, msh = energy.kin, problem.msh
    rec: dict = {"energy_share": _energy_shares(energy, msh)}
    for key, expr in (
        ("max_strain_l", abs(kin.lam - 1.0)),
        ("max_strain_m", abs(kin.mu - 1.0)),
        ("max_shear_deg", abs(kin.gamma) * (180.0 / np.pi)),
    ):
        e = quadrature_expression(ufl.as_ufl(expr), msh, energy.tension_degree)
        rec[key] = max_over_cells(e, msh)
    return rec


def _energy_shares(energy, msh) -> dict[str, float]:
    """Each term's share of the strain energy (its cell integral; the interior-penalty terms
    left out) at the current state, summed over the mesh's ranks."""
    parts = {}
    for t, c in energy.bound:
        density = t.density(energy.kin, c)
        if isinstance(density, float):
            continue
        dx = energy.dx_fibre if energy.reduced and t.fibre else energy.dx
        local = fem.assemble_scalar(fem.form(density * dx))
        parts[t.name] = max(float(msh.comm.allreduce(local, op=MPI.SUM)), 0.0)
    total = sum(parts.values())
    return {n: (v / total if total > 0 else 0.0) for n, v in parts.items()}


def stands_in_for(res: FitResult, name: str) -> tuple[str | None, float | None]:
    """(term, correlation): the other term whose fitted modulus correlates most with ``name``
    in the fit's covariance; (shear, None) without one."""
    free = [res.names[k] for k in res.free]
    cov = None if res.statistical is None else np.asarray(res.statistical.cov)
    term = name.split(".")[0]
    if cov is not None and name in free and cov.shape == (len(free), len(free)):
        i = free.index(name)
        sd = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        corr = cov[i] / (sd[i] * sd)
        others = [j for j, n in enumerate(free) if n.split(".")[0] != term]
        if others:
            j = max(others, key=lambda j: abs(corr[j]))
            return free[j].split(".")[0], float(corr[j])
    shear = "shear" if term != "shear" else None
    return shear, None


def check_moduli(
    fm,
    res: FitResult,
    plausible: dict | str | None = None,
    strain_bound: float = STRAIN_BOUND,
    say: bool = True,
) -> list[dict]:
    """The fitted moduli of ``res`` (on the forward model ``fm`` it was fitted on) that no
    fabric has, by the rules of the module docstring; with ``say``, each is warned once on
    rank 0 (:func:`say_implausible`). Costs a forward run when a yarn modulus is fitted."""
    ranges = parse_plausible(plausible)
    free = {res.names[k] for k in res.free}
    vals = dict(zip(res.names, np.asarray(res.values, dtype=float)))
    found = []
    fibres = [n for n in FIBRE_MODULI if n in free]
    strains = implied_strains(fm, res.values) if fibres else None
    yarn = [
        (n, q) for n in fibres if (q := _yarn_rule(strains or [], FIBRE_MODULI[n], strain_bound))
    ]
    corr = stands_in_for(res, yarn[0][0])[1] if yarn else None
    if yarn and (corr is None or abs(corr) >= CORRELATION):
        # one entry for the yarns: the first family's numbers, both families' moduli
        found.append(_entry(res, [n for n, _ in yarn], vals, yarn[0][1]))
    said = {m for q in found for m in q["moduli"]}
    for n, (lo, hi) in ranges.items():
        if n in vals and n in free and not lo <= vals[n] <= hi and n not in said:
            found.append(_entry(res, [n], vals, {"rule": "stated range", "range": [lo, hi]}))
    if say:
        say_implausible(found, fm.comm)
    return found


def say_implausible(found: list[dict] | None, comm: MPI.Comm) -> None:
    """Each record of :func:`check_moduli` as a warning, once, on rank 0."""
    for q in found or []:
        warn(logger, comm, "implausible modulus: " + q["text"])


def _yarn_rule(strains: list[dict], key: str, bound: float) -> dict | None:
    """The first experiment where the yarns stand in for shear (module docstring), as the
    numbers of the rule that says so; None if none."""
    for s in strains:
        eps, model = s.get(key), s.get("max_shear_deg")
        if eps is None or model is None:
            continue
        kin = s["kinematic_shear_deg"]
        numbers = {"experiment": s["experiment"], "yarn_strain": eps, "model_shear_deg": model}
        numbers["fibre_energy_share"] = s.get("energy_share", {}).get("fibre_stretch")
        if kin is not None and kin >= SHEAR_DEG:
            deficit = 1.0 - model / kin
            if deficit > DEFICIT:
                return numbers | {
                    "rule": "shear deficit",
                    "data_shear_deg": kin,
                    "deficit": deficit,
                }
        elif kin is None and model >= SHEAR_DEG and eps > bound:
            return numbers | {"rule": "yarn strain", "strain_bound": bound}
    return None


def _entry(res: FitResult, names: list[str], vals: dict, q: dict) -> dict:
    """The record of moduli ``names`` (of one term) that one rule found implausible."""
    n = names[0]
    term, p = n.split(".")
    unit = EFFECTS[term].units.get(p, "")
    other, corr = stands_in_for(res, n)
    value = ", ".join(f"{m.split('.')[1]} = {vals[m]:.4g}" for m in names)
    if q["rule"] == "shear deficit":
        why = (
            f"the model shears the fabric by at most {q['model_shear_deg']:.0f}° where the "
            f"data's grip displacement imposes {q['data_shear_deg']:.0f}° on yarns that do "
            f"not stretch ({100 * q['deficit']:.0f} % short, more than "
            f"{100 * DEFICIT:.0f} %): the yarns, stretching by up to "
            f"{100 * q['yarn_strain']:.2g} %, carry the rest"
        )
    elif q["rule"] == "yarn strain":
        why = (
            f"the yarns stretch by {100 * q['yarn_strain']:.2g} % in a test that shears the "
            f"fabric by {q['model_shear_deg']:.0f}° (real yarns: below "
            f"{100 * q['strain_bound']:.0f} %)"
        )
    else:
        why = f"outside the stated range {q['range'][0]:g}–{q['range'][1]:g} {unit}"
    instead = (
        f"it stands in for {other}"
        + (f" (correlation {corr:+.2f} in the fit's covariance)" if corr is not None else "")
        if other
        else "it stands in for an effect the model lacks"
    )
    advice = list(ADVICE) if term == "fibre_stretch" else [ADVICE[2]]
    return q | {
        "modulus": n,
        "value": float(vals[n]),
        "moduli": {m: float(vals[m]) for m in names},
        "unit": unit,
        "stands_in_for": other,
        "correlation": corr,
        "advice": advice,
        "text": f"{term}.{value} {unit}: {why}; {instead}. What to do: " + "; or ".join(advice),
    }
