"""The diagnosis result (diagnosis.json, contract version 2) and where a model still fails; the
results in words, as the command line prints them, are :mod:`~.result_text`'s."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.excess_text import outcome_text
from fabricsurf.inverse.diagnosis.ties import Tie
from fabricsurf.inverse.fitting.result import FitResult, strip_rows
from fabricsurf.model.terms import EFFECTS

UNCERTAINTY_KEYS = (
    "moduli",
    "identifiable_combinations",
    "weak_directions",
    "undetermined",
    "uncertainty",
    "at_stiff_limit",
)
"""The keys of a fit's intervals (:meth:`~.fit.FitResult.as_dict`) in the final model (the last
only when a modulus was held at its stiff limit)."""


@dataclass
class Diagnosis:
    """Everything diagnose found; :meth:`as_dict` is the diagnosis.json content."""

    baseline: list
    base_fit: FitResult
    final_fit: FitResult
    terms: list
    ranking: list
    rounds: list
    verdict: str | None
    adequate: bool
    path: list
    not_identifiable: list
    discretisation_chi2: float | None
    unexplained: dict | None
    fit_seconds: float
    noise_known: bool
    grip_depth: dict | None = None
    tie: Tie | None = None
    """The first round's best significant refit against the other refits (:mod:`~.ties`)."""
    separating_experiment: dict | None = None
    """For a tie: the experiments that would separate it, best first (:mod:`~.discrimination`,
    filled in by the caller: it costs forward runs)."""
    meshes: list | None = None
    """The mesh of each experiment (:meth:`~.forward.ForwardSet.meshes`)."""
    mesh_selection: dict | None = None
    """The meshes tried and why the refinement stopped (:mod:`~.mesh_choice`); None when the
    diagnosis ran on one mesh only."""
    beyond: dict | None = None
    """The search beyond the vocabulary on the final mesh (:func:`~.beyond.search_beyond`);
    None when it was not asked for."""
    carried: list | None = None
    """The final fit's converged states per experiment (forward.warm_start.carry), from which
    the search beyond the vocabulary starts its forward set; not written out."""
    excess_location: dict | None = None
    """Where the final model's field excess sits: at the grips and zone boundaries or spread
    (:func:`~.excess.excess_location`)."""
    implausible: list | None = None
    """The final model's fitted moduli no fabric has
    (:func:`~fabricsurf.inverse.fitting.plausibility.check_moduli`)."""

    def tied(self) -> list[str] | None:
        """The effects the data cannot tell apart, the verdict first (None: no tie)."""
        return self.tie.members if self.tie is not None and self.tie.tied else None

    @property
    def alternatives(self) -> list[str]:
        """The other effects of a tie (empty without one): the data cannot tell them from the
        verdict."""
        return self.tie.others() if self.tie is not None else []

    def verdict_text(self) -> str | None:
        """The verdict as a user reads it: "a or b" for a tie."""
        return " or ".join(self.tied() or [self.verdict]) if self.verdict else None

    def too_coarse(self) -> bool:
        """The h/2 check says the mesh is too coarse for these data (:func:`~.sg.too_coarse`)."""
        return self.discretisation_chi2 is not None and sg.too_coarse(
            self.discretisation_chi2, self.final_fit.misfit["n"], len(self.final_fit.names)
        )

    def outcome(self) -> str:
        if self.verdict is not None:
            text = (
                f"add {self.verdict_text()}"
                + (" (a tie: the data cannot tell them apart)" if self.tied() else "")
                + ("" if self.adequate else " (still not adequate)")
            )
        else:
            text = "nothing missing" if self.adequate else "unexplained misfit"
        if self.beyond and self.beyond.get("found"):
            text += "; beyond the vocabulary: " + self.beyond["outcome"]
        return text + self.mesh_note()

    def notes(self) -> list[str]:
        """What the outcome (one of the contract's three, :meth:`outcome`) leaves to be said:
        where the excess sits when the model is not adequate (:mod:`~.excess`), and each
        fitted modulus no fabric has, with the effect it stands in for and what to do
        (:mod:`~fabricsurf.inverse.fitting.plausibility`)."""
        out = [outcome_text(self.excess_location)] if not self.adequate else []
        if out and out[0] and self.too_coarse():  # the mesh's own error is spread too
            out[0] += "; but the h/2 check calls the mesh too coarse: refine h before reading it"
        out += [f"implausible modulus: {q['text']}" for q in self.implausible or []]
        if self.too_coarse():  # the mesh selection's advice on stiff yarns, if it gave one
            out.append((self.mesh_selection or {}).get("yarn_note"))
        return [t for t in out if t]

    def mesh_note(self) -> str:
        """ "" when the mesh is fine enough; else "refine h", with why the mesh selection (if it
        ran) refined no further: its budget, spent."""
        if not self.too_coarse():
            return ""
        why = (self.mesh_selection or {}).get("stopped")
        return "; the mesh is too coarse for these data (refine h)" + (f": {why}" if why else "")

    def as_dict(self) -> dict:
        b, f = self.base_fit, self.final_fit
        n = f.misfit["n"]
        return {
            "contract_version": 2,
            "baseline": {
                "terms": self.baseline,
                "misfit": b.misfit["combined"],
                "chi2": b.chi2,
                "n": b.misfit["n"],
                "params": b.params(),
                "std": b.as_dict()["std"],
            },
            "ranking": self.ranking,
            "rounds": self.rounds,
            "verdict": self.verdict,
            "tie": self.tied(),
            "tie_test": None if self.tie is None else self.tie.as_dict(),
            "separating_experiment": self.separating_experiment,
            "indistinguishable_from_verdict": self.alternatives,
            "adequate": self.adequate,
            "outcome": self.outcome(),
            "outcome_notes": self.notes(),
            "path": self.path,
            "final": {"terms": self.terms, "params": f.params(), "std": f.as_dict()["std"]}
            | {k: v for k, v in f.as_dict().items() if k in UNCERTAINTY_KEYS}
            | {"misfit": strip_rows(f.misfit)},
            "not_identifiable": self.not_identifiable,
            "unexplained": self.unexplained,
            "discretisation": {
                "chi2_h_vs_h2": self.discretisation_chi2,
                "misfit": (
                    None
                    if self.discretisation_chi2 is None
                    else float(np.sqrt(self.discretisation_chi2 / max(n, 1)))
                ),
                "too_coarse": self.too_coarse(),
                "meshes": self.meshes,
                "mesh_selection": self.mesh_selection,
            },
            "significance": {
                "level": sg.LEVEL,
                "test": "Wald, cluster-robust covariance",
                "adequacy_bound": sg.adequacy_bound(n, len(f.names)),
                "noise_known": self.noise_known,
                "rule": sg.__doc__.split("*Adequate*")[1].strip(),
            },
            "grip_depth": self.grip_depth,
            "beyond_vocabulary": self.beyond,
            "excess_location": self.excess_location,
            "implausible_moduli": self.implausible,
            "seconds": {"baseline_fit": self.fit_seconds},
        }


def look_alikes(effects: list[str], exps: list) -> list[dict]:
    """The effects among ``effects`` that these data cannot tell from a mechanism outside the
    vocabulary (a term's ``look_alike``: the mechanism, the evidence, the data that would
    identify it), when the data are force curves of one specimen size only."""
    if any(e.has_field for e in exps) or len({(e.length, e.width) for e in exps}) > 1:
        return []
    return [
        {
            "effect": n,
            "reason": "one force curve cannot tell it from " + EFFECTS[n].look_alike["mechanism"],
        }
        | EFFECTS[n].look_alike
        for n in dict.fromkeys(effects)
        if getattr(EFFECTS[n], "look_alike", None)
    ]


def _force_ranges(exp, per_step: list, s_F: float) -> list:
    """Load-path ranges where the force error exceeds three noise levels."""
    bad = [abs(q.get("force_error", 0.0)) > 3 * s_F for q in per_step]
    ranges, start = [], None
    for k, b in enumerate(bad + [False]):
        if b and start is None:
            start = k
        if not b and start is not None:
            ranges.append([float(exp.path[start]), float(exp.path[k - 1])])
            start = None
    return ranges


def _regions(exp, err: np.ndarray, s_u: float, blocks: int = 3) -> list:
    """RMS field error (noise units) over a blocks × blocks grid of the specimen, worst first."""
    ix = np.minimum((exp.X[:, 0] / exp.length * blocks).astype(int), blocks - 1)
    iy = np.minimum((exp.X[:, 1] / exp.width * blocks).astype(int), blocks - 1)
    out = []
    for i in range(blocks):
        for j in range(blocks):
            sel = (ix == i) & (iy == j) & np.isfinite(err)
            if sel.any():
                out.append(
                    {
                        "x_mm": [exp.length * i / blocks, exp.length * (i + 1) / blocks],
                        "y_mm": [exp.width * j / blocks, exp.width * (j + 1) / blocks],
                        "rms_noise_units": float(np.sqrt(np.mean(err[sel] ** 2)) / s_u),
                    }
                )
    return sorted(out, key=lambda q: -q["rms_noise_units"])


def best_lead(rows: list, res: FitResult, p: int) -> dict | None:
    """The refitted candidate that came closest, and by how much it missed the rule: what to
    look at first when the misfit stays unexplained."""
    tried = [q for q in rows if q.get("refit_chi2") is not None]
    if not tried:
        return None
    q = min(tried, key=lambda r: r["refit_chi2"])
    n, k = res.misfit["n"], len(q.get("refit_std") or {}) or 1
    return {
        "effect": q["effect"],
        "refit_misfit": q["refit_misfit"],
        "share_of_excess": sg.share_of_excess(res.chi2, p, q["refit_chi2"], n),
        "f_test_passed": sg.f_test(res.chi2, p, q["refit_chi2"], p + k, n),
        "wald_p": q.get("wald_p"),
        "wald_p_needed": 1.0 - sg.LEVEL,
    }


def where_unexplained(exps: list, res: FitResult, lead: dict | None = None) -> dict:
    """Per experiment: the worst steps, the load ranges with force errors beyond 3σ, the worst
    regions of the specimen; ``best_lead`` (:func:`best_lead`) when a candidate was refitted."""
    per = res.misfit["experiments"] if "experiments" in res.misfit else [res.misfit]
    out = []
    for exp, m in zip(exps, per):
        steps = sorted(m["per_step"], key=lambda q: -q["combined"])[:3]
        item = {
            "experiment": exp.name,
            "worst_steps": [
                {"step": q["step"], "load": q["load"], "misfit": q["combined"]} for q in steps
            ],
        }
        if exp.has_force:
            item["force_error_ranges"] = _force_ranges(exp, m["per_step"], m["s_F"])
        if exp.has_field:
            item["worst_regions"] = _regions(exp, m["row_error"], m["s_u"])[:3]
        out.append(item)
    return {
        "experiments": out,
        "best_lead": lead,
        "figure": "error_vs_step.png and error_map.png of the final model",
    }
