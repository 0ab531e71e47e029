"""Which physical effect is missing? (DESIGN §7)

1. Fit the baseline terms (:func:`fabricsurf.inverse.fit.fit`).
2. Rank every vocabulary effect not in the baseline with one forward run: the model holds all
   in-plane effects (EFFECTS order, so one compiled form serves every diagnosis), candidates at
   modulus 0, so the state is the baseline fit; tangent solves give dr/dp for every modulus.
   The score of candidate c is the χ² reduction predicted by linearising about the baseline
   with c's modulus (in the modulus itself, ≥ 0) as an extra parameter, the baseline moduli
   free: with s⊥ = dr/dp_c projected off the baseline sensitivities, score = (s⊥·r)²/|s⊥|²
   if the estimated modulus −(s⊥·r)/|s⊥|² is positive, else 0.
3. Confirm the ``confirm`` best-scored candidates by refitting baseline + candidate.
4. Significance against the noise (residuals are normalised by the noise level):
   Δχ² = χ²_baseline − χ²_refit > 10.83 (the 0.999 quantile of χ²₁) and the baseline itself
   fails at the noise level, χ²_baseline/ν > 1 + 3√(2/ν). Without ``noise_std`` an F-test at
   0.999 replaces both. The verdict is the significant confirmed candidate with the lowest
   refit χ², or None; significant candidates whose refit χ² is within 10.83 of the verdict's
   are listed as indistinguishable from it by these data. Effects planar data cannot see are
   reported as not identifiable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from scipy import stats

from fabricsurf.inverse.compare import ForwardModel, Prediction, residuals
from fabricsurf.inverse.fit import FitResult, fit
from fabricsurf.model.terms import EFFECTS, IN_PLANE_INVISIBLE, make_term

CHI2_CRIT = float(stats.chi2.ppf(0.999, 1))


@dataclass
class Diagnosis:
    """The diagnosis.json content (:meth:`as_dict`) plus the fits behind it."""

    baseline: list
    base_fit: FitResult
    ranking: list
    verdict: str | None
    alternatives: list
    not_identifiable: list
    refits: dict
    rank_seconds: float
    forward_seconds: float

    def as_dict(self) -> dict:
        b = self.base_fit
        return {"baseline": {"terms": self.baseline, "misfit": b.misfit["combined"],
                             "chi2": b.chi2, "n": b.misfit["n"], "params": b.params(),
                             "std": b.as_dict()["std"]},
                "ranking": self.ranking, "verdict": self.verdict,
                "indistinguishable_from_verdict": self.alternatives,
                "not_identifiable": self.not_identifiable,
                "significance": {"chi2_critical": CHI2_CRIT, "rule": __doc__.split("4.")[1]
                                 .split("The verdict")[0].strip()},
                "cost": {"rank_seconds": self.rank_seconds,
                         "forward_seconds": self.forward_seconds,
                         "rank_over_forward": self.rank_seconds / self.forward_seconds}}


def full_model(baseline: list[str], params: dict | None = None) -> list:
    """Baseline + every identifiable in-plane effect, in EFFECTS order; candidates at 0."""
    params = params or {}
    names = [n for n in EFFECTS if n in baseline or n not in IN_PLANE_INVISIBLE]
    model = []
    for n in names:
        t = make_term(n, **params.get(n, {}))
        if n not in baseline:
            t.set(**{p: 0.0 for p in t.parameters()})
        model.append(t)
    return model


def scores(r: np.ndarray, Jr: np.ndarray, vals: np.ndarray, base: list[int],
           cand: dict[str, list[int]]) -> dict[str, tuple[float, float]]:
    """Linearised χ² reduction and modulus estimate per candidate (module docstring)."""
    Q, _ = np.linalg.qr(Jr[:, base] * vals[base])
    out = {}
    for name, idx in cand.items():
        s = Jr[:, idx].sum(axis=1)  # all moduli of the candidate together (k_l = k_m style)
        s = s - Q @ (Q.T @ s)
        ss = float(s @ s)
        est = -float(s @ r) / ss if ss > 0 else 0.0
        out[name] = (float(s @ r) ** 2 / ss if est > 0 else 0.0, est)
    return out


def significant(chi2_base: float, chi2_new: float, n: int, p_new: int,
                noise_known: bool) -> bool:
    """The significance rule of the module docstring."""
    d = chi2_base - chi2_new
    if noise_known:
        nu = max(n - p_new + 1, 1)
        return bool(d > CHI2_CRIT and chi2_base / nu > 1 + 3 * np.sqrt(2 / nu))
    dof = max(n - p_new, 1)
    return bool(d / (chi2_new / dof) > stats.f.ppf(0.999, 1, dof))


def _rank(fm: ForwardModel, base_idx: list[int], cand: dict) -> tuple[dict, float, Prediction]:
    t0 = MPI.Wtime()
    pred = fm.run(sens=True)
    r, Jr = residuals(fm.exp, pred)
    return scores(r, Jr, fm.values(), base_idx, cand), MPI.Wtime() - t0, pred


def _refit(fm: ForwardModel, base_vals: np.ndarray, base_idx: list[int], idx: list[int],
           estimate: float, verbose: bool) -> FitResult:
    v = base_vals.copy()
    v[idx] = max(estimate, 1e-3 * float(np.max(base_vals[base_idx])))
    fm.set_values(v)
    res = fit(fm, base_idx + idx, verbose=verbose)
    fm.set_values(base_vals)
    return res


def diagnose(exp, baseline: list[str], h: float | None = None, params: dict | None = None,
             confirm: int = 2, comm: MPI.Comm = MPI.COMM_WORLD,
             verbose: bool = True) -> Diagnosis:
    """Fit ``baseline``, rank the missing effects, confirm the best ``confirm`` by refitting."""
    for n in baseline:
        make_term(n)  # validates the names
    fm = ForwardModel(exp, full_model(baseline, params), h=h, comm=comm)
    idx_of = {n: [i for i, (t, _) in enumerate(fm.params) if t.name == n] for n in EFFECTS}
    base_idx = sorted(i for n in baseline for i in idx_of[n])
    cand = {n: idx_of[n] for n in EFFECTS if n not in baseline and n not in IN_PLANE_INVISIBLE}
    base = fit(fm, base_idx, verbose=verbose)
    t0 = MPI.Wtime()
    fm.run()
    t_fwd = MPI.Wtime() - t0
    sc, t_rank, _ = _rank(fm, base_idx, cand)
    order = sorted(cand, key=lambda c: -sc[c][0])
    refits, noise = {}, exp.noise_std is not None
    for c in order[:confirm]:
        refits[c] = _refit(fm, base.values, base_idx, cand[c], sc[c][1], verbose)
    ranking = []
    for c in order:
        row = {"effect": c, "score": sc[c][0], "linearised_modulus": sc[c][1],
               "refit_misfit": None, "significant": None}
        if c in refits:
            rf = refits[c]
            row.update(refit_misfit=rf.misfit["combined"], refit_chi2=rf.chi2,
                       refit_params=rf.params()[c], refit_std={
                           n: float(s) for n, s in zip(rf.names, rf.std) if n.startswith(c)},
                       significant=significant(base.chi2, rf.chi2, rf.misfit["n"],
                                               len(base_idx) + len(cand[c]), noise))
        ranking.append(row)
    ranking.sort(key=lambda r: (1, -r["score"]) if r["refit_misfit"] is None
                 else (0, r["refit_misfit"]))
    sig = [r for r in ranking if r["significant"]]
    verdict = sig[0]["effect"] if sig else None
    alternatives = [r["effect"] for r in sig[1:]
                    if r["refit_chi2"] - sig[0]["refit_chi2"] < CHI2_CRIT]
    invisible = [{"effect": n, "reason": "planar (2D) data cannot see out-of-plane effects"}
                 for n in IN_PLANE_INVISIBLE if n not in baseline]
    return Diagnosis(list(baseline), base, ranking, verdict, alternatives, invisible, refits,
                     t_rank, t_fwd)
