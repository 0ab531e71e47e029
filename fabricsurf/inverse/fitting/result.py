"""The result of a fit: the fitted moduli with their uncertainties (statistical, model form and,
after :meth:`FitResult.check_mesh`, mesh; docs/uncertainty.md) and misfits, JSON-ready."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from fabricsurf.inverse.forward.load_path import Prediction
from fabricsurf.inverse.forward.runs import ForwardModel, ForwardSet
from fabricsurf.inverse.uncertainty import intervals, systematic
from fabricsurf.inverse.uncertainty import statistical as unc
from fabricsurf.model.stability import TangentCheck

OMITS_INTERVALS = (
    "the size part: moduli fitted on one specimen carry its share of effects "
    "with a length, wrong for another size (size_form.size_record; "
    "docs/uncertainty.md)"
)
"""What the intervals of a fit on one specimen size leave out (:mod:`size_form`)."""


@dataclass
class FitResult:
    """Fitted moduli (by parameter name "term.param"), their statistical standard deviations,
    misfits; ``J``, ``r``, ``blocks``: the sensitivities dr/dp of the ``free`` moduli, the
    residuals and their block labels at the optimum (for the uncertainty)."""

    names: list
    values: np.ndarray
    std: np.ndarray
    chi2: float
    misfit: dict
    prediction: Prediction | list[Prediction]
    iterations: int
    forward_runs: int
    history: list = field(default_factory=list)
    undetermined: list = field(default_factory=list)
    """Combinations of log-moduli the data do not determine (:func:`~.optimum.undetermined`)."""
    free: list = field(default_factory=list)
    J: np.ndarray | None = None
    r: np.ndarray | None = None
    statistical: unc.Statistical | None = None
    model_form: np.ndarray | None = None
    mesh_shift: np.ndarray | None = None
    chi2_h: float | None = None
    mesh_difference: np.ndarray | None = None
    """d = r_{h/2} − r_h at the fitted moduli, when the h/2 check ran (:meth:`check_mesh`)."""
    size_effects: dict | None = None
    """The size part's record (:func:`~.size_form.size_record`), when it was estimated."""
    implausible: list | None = None
    """The fitted moduli no fabric has (:func:`~.plausibility.check_moduli`), when checked."""
    stability: TangentCheck | None = None
    """For a model with a signed modulus, its fitted energy's stability over the data's states
    (:func:`~.stability_check.fitted_tangent`)."""
    at_limit: dict | None = None
    """The moduli held at their stiff limit (:mod:`~.stiff_limit`): {name: the χ² gain left
    between there and infinity}."""

    def params(self) -> dict:
        """{term: {param: value}} (the --params file format)."""
        out: dict = {}
        for n, v in zip(self.names, self.values):
            t, p = n.split(".")
            out.setdefault(t, {})[p] = float(v)
        return out

    def check_mesh(self, fm: Forward, d: np.ndarray | None = None) -> None:
        """The mesh part (:func:`~.systematic.mesh_shift`): the residual difference ``d``
        between h and h/2 at the fitted moduli, run here when not given."""
        if self.J is None:
            return
        d = systematic.mesh_difference(fm, self.prediction, fm.comm) if d is None else d
        self.chi2_h = float(d @ d)
        self.mesh_difference = d
        self.mesh_shift = systematic.mesh_shift(self.J, d)

    def lost(self) -> set[str]:
        """The moduli in a null direction of the Fisher matrix (:attr:`undetermined`)."""
        return {n for c in self.undetermined for n in re.findall(r"[A-Za-z_]\w*\.\w+", c)}

    def std_dict(self) -> dict:
        """{name: standard deviation}, None for a modulus the data do not determine (the
        pseudo-inverse gives it a variance of 0 in the null direction, which is not "known
        exactly": :func:`~.optimum.undetermined` names the combination)."""
        return {n: float(s) if np.isfinite(s) else None for n, s in zip(self.names, self.std)}

    def uncertainty(self) -> dict:
        """The per-modulus intervals and identifiable combinations (:mod:`~.intervals`)."""
        if self.statistical is None:
            return {"moduli": {}, "identifiable_combinations": [], "weak_directions": []}
        free = self.free
        lost = self.lost()
        size = (
            None
            if self.size_effects is None
            else np.array(
                [self.size_effects["moduli_half_width"].get(self.names[k], 0.0) for k in free]
            )
        )
        null = (
            None
            if self.J is None
            else intervals.null_directions(
                intervals.scaled_jacobian(self.J, self.values[free], [self.names[k] for k in free])
            )
        )
        out = intervals.summarise(
            [self.names[k] for k in free],
            self.values[free],
            self.statistical.cov,
            self.statistical.t95(),
            self.model_form,
            self.mesh_shift,
            lost,
            size,
            null,
        )
        for k, n in enumerate(self.names):
            if k not in free and self.values[k] > 0:  # held at a given modulus
                out["moduli"][n] = {"value": float(self.values[k]), "fixed": True}
        cov = {"names": [self.names[k] for k in free], "statistical": self.statistical.cov.tolist()}
        parts = ["statistical"] + [
            k
            for k, v in (
                ("model_form", self.model_form),
                ("mesh", self.mesh_shift),
                ("size_form", self.size_effects),
            )
            if v is not None
        ]
        return out | {
            "statistics": self.statistical.as_dict(len(self.r)),
            "chi2_h_vs_h2": self.chi2_h,
            "covariance": cov,
            "interval_parts": parts,
            "interval_omits": [] if self.size_effects else [OMITS_INTERVALS],
        }

    def as_dict(self) -> dict:
        m = strip_rows(self.misfit)
        u = self.uncertainty()
        return (
            {
                "terms": list(self.params()),
                "params": self.params(),
                "std": self.std_dict(),
                "moduli": u["moduli"],
                "identifiable_combinations": u["identifiable_combinations"],
                "weak_directions": u["weak_directions"],
                "uncertainty": {
                    k: u.get(k)
                    for k in (
                        "statistics",
                        "chi2_h_vs_h2",
                        "covariance",
                        "interval_parts",
                        "interval_omits",
                    )
                },
                "chi2": self.chi2,
                "misfit": m,
                "iterations": self.iterations,
                "forward_runs": self.forward_runs,
                "history": self.history,
                "undetermined": self.undetermined,
            }
            | ({"size_effects": self.size_effects} if self.size_effects else {})
            | ({} if self.implausible is None else {"implausible_moduli": self.implausible})
            | ({"stability": self.stability.as_dict()} if self.stability else {})
            | ({"at_stiff_limit": self.at_limit} if self.at_limit else {})
        )


Forward = ForwardModel | ForwardSet


def strip_rows(m: dict) -> dict:
    """A misfit dict without the per-row error arrays (for JSON)."""
    out = {k: v for k, v in m.items() if k not in ("row_error", "shear_error")}
    if "experiments" in out:
        out["experiments"] = [strip_rows(e) for e in out["experiments"]]
    return out
