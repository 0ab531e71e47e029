"""The cantilever bending test of fabrics (Peirce 1930; ASTM D1388) as a 3D experiment plug-in.

A strip [0, length] × [0, width] (x along the strip, mm) with fibres at ``fibre_angles_deg`` to
the strip axis is clamped at x = 0 (u = 0 and ∂ₙu = 0, weakly, like the bias-test clamps) and
free elsewhere; it sags under its own weight, a dead load b = −t ρ_A g e_z per unit reference
area, ramped by the self-weight factor t (the load path, dimensionless; t = 1 is the full
weight). Observed: 3D displacements at points (a laser or stereo-DIC profile); helpers give the
tip deflection and run a finer ramp. No reaction is measured.

Units: the areal density ρ_A is given in g/m² (``[material] areal_density_g_m2``); with
1 g/m² = 1e-3 kg / 1e6 mm² = 1e-9 kg/mm², g = 9.81 m/s² = 9.81e3 mm/s² and 1 kg·mm/s² = 1e-3 N,
ρ_A g = ρ_A · 9.81e-9 N/mm² (200 g/m² → 1.962 N/m² = 1.962e-6 N/mm²).

The moduli that matter are normal_bending (k_b) and twist (k_t); fibre_stretch and shear keep
the strip nearly inextensible in its plane. A strip whose fibres are both off its axis (e.g.
±45°) is a near-mechanism without twist: its fibres can become the asymptotic lines of an
anticlastic surface (K_L = K_M = 0), and its narrow-strip rigidity 2k_b k_t/(k_t + 2k_b) vanishes
with k_t (docs/bending.md); only the clamp's boundary layer and the membrane resist.
:meth:`CantileverPlugin.mechanism_note` says so (a warning when the plug-in is built, appended
to the error of a failed :meth:`~CantileverPlugin.run`); the solve then converges to that very
soft state or fails with that message, never silently.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.energy import has_second_gradient
from fabricsurf.discretise.evaluation import eval_points
from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.discretise.stepping import LoadStepError, LoadStepper
from fabricsurf.errors import DataError
from fabricsurf.experiments.base import ExperimentPlugin, PluginSetup, number_option
from fabricsurf.geometry.specimen import structured_rectangle
from fabricsurf.log import warn
from fabricsurf.model.rigidity import cylindrical_rigidity, narrow_strip_rigidity
from fabricsurf.model.terms import Term

logger = logging.getLogger(__name__)
GRAVITY = 9.81
"""m/s², along −z."""
MECHANISM_RATIO = 0.05
"""Narrow-strip over cylindrical rigidity below which the strip is called a near-mechanism."""


def weight_per_area(areal_density_g_m2: float) -> float:
    """ρ_A g in N/mm² from ρ_A in g/m² (module docstring: ρ_A · 1e-9 kg/mm² · 9.81e3 mm/s² ·
    1e-3 N/(kg·mm/s²))."""
    return areal_density_g_m2 * 1e-9 * (GRAVITY * 1e3) * 1e-3


def areal_density_option(tables: dict, where: str, default: float | None = None) -> float:
    """``[material] areal_density_g_m2`` (g/m²), checked to be a plausible fabric; required
    when ``default`` is None (a default is returned as it is)."""
    if default is not None and "areal_density_g_m2" not in tables.get("material", {}):
        return default
    rho = number_option(tables, "material", "areal_density_g_m2", where)
    if not 1.0 <= rho <= 5000.0:
        raise DataError(
            f"{where}: [material] areal_density_g_m2 = {rho:g} g/m² is not a "
            "plausible fabric (1 to 5000 g/m²): is it in another unit?"
        )
    return rho


def rigidity_uNm(rigidity_N_mm: float) -> float:
    """Bending rigidity per unit width in the textile unit µN·m (= µN·m²/m) from N·mm
    (1 N·mm = 1e-3 N·m = 1e3 µN·m)."""
    return 1e3 * rigidity_N_mm


def moduli(model: list[Term]) -> tuple[float, float]:
    """(k_b, k_t) of a model (0 for a term it lacks)."""
    vals = {t.name: t.values() for t in model}
    return (vals.get("normal_bending", {}).get("k_b", 0.0), vals.get("twist", {}).get("k_t", 0.0))


class CantileverPlugin(ExperimentPlugin):
    """Plug-in: strip clamped at x = 0 sagging under its own weight (module docstring).
    Load path: the self-weight factor t; observed: u (3 components) at points."""

    name = "cantilever"
    d = 3
    path_unit = "1"
    has_reaction = False
    path_label = "self-weight factor"
    weak_terms = ("fibre_stretch", "shear", "shear_locking")  # the strip hardly strains in-plane
    bends = "cantilever"
    keys = {
        "material": {
            "areal_density_g_m2": "areal density (g/m²), gravity 9.81 m/s² along −z (required)"
        }
    }

    def __init__(
        self, setup: PluginSetup, model: list[Term], h: float, comm: MPI.Comm = MPI.COMM_WORLD
    ) -> None:
        super().__init__(setup, model, h, comm)
        if not has_second_gradient(model):
            raise ValueError(
                "cantilever: the model has no second-gradient term, so the strip "
                "has no bending stiffness at all; add normal_bending (and twist)"
            )
        L, w = setup.length, setup.width
        self.specimen = structured_rectangle(L, w, max(2, round(L / h)), max(1, round(w / h)), comm)
        p = FabricProblem(
            self.specimen,
            self.model,
            d=3,
            fibre_angles=tuple(setup.fibre_angles_deg),
            prefix="fabricsurf_cantilever_",
        )
        p.fix("clamp", (0.0, 0.0, 0.0))
        p.clamp_gradient("clamp")
        self.weight = weight_per_area(setup.options["areal_density_g_m2"])
        self._q = fem.Constant(p.msh, 0.0)
        p.add_body_force(ufl.as_vector([0.0, 0.0, -self._q]))
        self.problem, self.solver = p, p.solver()
        self.tip = np.array([[L, 0.5 * w]])
        note = self.mechanism_note()
        if note is not None:
            warn(logger, comm, note)

    @classmethod
    def parse_options(cls, tables: dict, length_scale: float, where: str) -> dict:
        return {"areal_density_g_m2": areal_density_option(tables, where)}

    @classmethod
    def check_path(cls, steps, path, where: str) -> None:
        """The self-weight factor lies in (0, 1]: a fraction of the weight, downward."""
        bad = [k for k, v in enumerate(path) if not 0 < v <= 1]
        if bad:
            k = bad[0]
            raise DataError(
                f"{where}: step {int(steps[k])}: self-weight factor {path[k]:g} "
                "is outside (0, 1]; the cantilever sags under a fraction t of its "
                "own weight (t = 1: the full weight)"
            )

    @classmethod
    def default_h(cls, setup: PluginSetup) -> float:
        return min(setup.length / 16.0, setup.width / 2.0)

    def set_load(self, t: float) -> None:
        self._q.value = float(t) * self.weight

    def displacement_at(self, points: np.ndarray) -> np.ndarray:
        """u (n×3) at reference points (n×2), the same on every rank."""
        return eval_points(self.problem.u, points)

    def tip_deflection(self) -> float:
        """δ = −u_z at the middle of the free end (mm, positive downwards)."""
        return float(-self.displacement_at(self.tip)[0, 2])

    def chord_angle(self) -> float:
        """Angle below the horizontal of the chord from the clamp to the tip (rad)."""
        u = self.displacement_at(self.tip)[0]
        return math.atan2(-u[2], self.setup.length + u[0])

    def mechanism_note(self) -> str | None:
        """A message when the current moduli make the strip a near-mechanism (module
        docstring), else None."""
        k_b, k_t = moduli(self.model)
        angles = tuple(self.setup.fibre_angles_deg)
        narrow = max(narrow_strip_rigidity(k_b, k_t, angles), 0.0)
        cyl = cylindrical_rigidity(k_b, k_t, angles)
        if narrow >= MECHANISM_RATIO * cyl:
            return None
        return (
            f"cantilever: with fibres at {list(angles)} deg and k_t = {k_t:g} N·mm the "
            f"narrow-strip rigidity {narrow:.3g} N·mm is {narrow / cyl:.2g} of the "
            f"cylindrical one {cyl:.3g} N·mm: a near-mechanism (fibres along the asymptotic "
            "lines of an anticlastic surface); only the clamp and the membrane resist, so "
            "expect a very soft strip or a failed load step. Add twist (k_t > 0)."
        )

    def run(
        self,
        t_max: float = 1.0,
        steps: int = 8,
        on_step: Callable[[int, float], None] | None = None,
    ) -> list[int]:
        """Ramp the self-weight from the reference state to ``t_max`` in ``steps`` equal
        requested steps (cut automatically on divergence); ``on_step(k, t)`` after each (all
        ranks). Returns the Newton iterations per step."""
        self.solver.u.x.array[:] = 0.0
        self.set_load(0.0)
        done = (lambda k, t, its: on_step(k, t)) if on_step is not None else None
        try:
            return LoadStepper(self.solver, self.set_load, done).run(
                np.linspace(t_max / steps, t_max, steps)
            )
        except LoadStepError as e:
            note = self.mechanism_note()
            raise e.carrying(f"{e}" + (f"\n{note}" if note else "")) from e
