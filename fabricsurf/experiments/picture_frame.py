"""The picture-frame (trellis) shear test (Cao et al. 2008 §4) as an experiment plug-in.

A square specimen of side a (hinge to hinge) sits in a rigid frame of four bars hinged at the
corners; the fibres run along the bars ([0, 90]); the crosshead pulls the corner (a, a) along
the diagonal by d while (0, 0) stays put. The frame is a rhombus of side a with diagonal
D = a√2 + d, so the half-angle φ between a bar and the diagonal has cos φ = D/(2a), and the bars
point along e₁ = (cos(π/4 − φ), sin(π/4 − φ)) and e₂ = (cos(π/4 + φ), sin(π/4 + φ)). The frame
prescribes the homogeneous placement r = F₀X, F₀ = [e₁ e₂], on the whole boundary:

* ``frame = "pinned"``: positions only (fibres free to rotate at the bars);
* ``frame = "clamped"``: also the normal derivative ∂ₙu = (F₀ − I)n (fibres clamped in the
  bars), imposed weakly like the bias-test clamps.

The frame shear angle is γ = π/2 − 2φ. With the fibres along the bars the homogeneous pure
shear is the exact solution for every energy of the vocabulary (its second gradient vanishes),
and the crosshead force is F = a² W′(γ) dγ/dd with dγ/dd = 1/(a sin φ)
(:func:`frame_force_exact`). Reaction: the virtual work R(u)·∂u_frame/∂d.
"""

from __future__ import annotations

import math

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.errors import DataError
from fabricsurf.experiments.base import ExperimentPlugin, PluginSetup, choice_option
from fabricsurf.geometry.specimen import EDGE_TAGS, rectangle
from fabricsurf.model.terms import Term

FRAMES = ("pinned", "clamped")


def frame_half_angle(d: float, a: float) -> float:
    """φ with cos φ = (a√2 + d)/(2a); the frame locks flat when the diagonal reaches 2a."""
    c = (a * math.sqrt(2.0) + d) / (2.0 * a)
    if not -1.0 < c < 1.0:
        raise ValueError(
            f"picture frame: crosshead displacement {d:g} mm is beyond the frame's "
            f"range ({-a * math.sqrt(2):.4g}, {a * (2 - math.sqrt(2)):.4g}) mm"
        )
    return math.acos(c)


def frame_shear_angle(d: float, a: float) -> float:
    """γ = π/2 − 2φ (rad)."""
    return 0.5 * math.pi - 2.0 * frame_half_angle(d, a)


def frame_displacement(gamma: float, a: float) -> float:
    """The crosshead displacement d at which the frame's shear angle is ``gamma`` (rad), the
    inverse of :func:`frame_shear_angle`: d = 2a cos φ − a√2 with φ = π/4 − γ/2."""
    return 2.0 * a * math.cos(0.25 * math.pi - 0.5 * gamma) - a * math.sqrt(2.0)


def frame_gradient(d: float, a: float) -> tuple[np.ndarray, np.ndarray]:
    """F₀ = [e₁ e₂] and dF₀/dd."""
    phi = frame_half_angle(d, a)
    q = 0.25 * math.pi
    F0 = np.array([[math.cos(q - phi), math.cos(q + phi)], [math.sin(q - phi), math.sin(q + phi)]])
    dF0_dphi = np.array(
        [[math.sin(q - phi), -math.sin(q + phi)], [-math.cos(q - phi), math.cos(q + phi)]]
    )
    return F0, dF0_dphi * (-1.0 / (2.0 * a * math.sin(phi)))


def frame_force_exact(d: float, a: float, dW_dgamma) -> float:
    """Crosshead force of the homogeneous solution: a² W′(γ)/(a sin φ) (N)."""
    phi = frame_half_angle(d, a)
    return a * a * dW_dgamma(frame_shear_angle(d, a)) / (a * math.sin(phi))


class PictureFramePlugin(ExperimentPlugin):
    """Plug-in: square specimen in a hinged frame pulled along the diagonal (module docstring).
    Load path: crosshead displacement (mm); reaction: crosshead force along the diagonal (N)."""

    name = "picture_frame"
    path_label = "crosshead displacement (mm)"
    reaction_label = "crosshead force (N)"
    keys = {"loading": {"frame": "pinned | clamped (default pinned)"}}

    def __init__(
        self, setup: PluginSetup, model: list[Term], h: float, comm: MPI.Comm = MPI.COMM_WORLD
    ) -> None:
        super().__init__(setup, model, h, comm)
        self.a = setup.length
        specimen = rectangle(self.a, self.a, h, comm)
        p = FabricProblem(
            specimen,
            self.model,
            d=2,
            fibre_angles=tuple(setup.fibre_angles_deg),
            prefix="fabricsurf_frame_",
        )
        V = p.V
        self._g, self._w = fem.Function(V), fem.Function(V)
        for edge in EDGE_TAGS:
            p.fix_function(edge, self._g)
        self._F0 = fem.Constant(p.msh, np.eye(2))
        if setup.options.get("frame", "pinned") == "clamped":
            p.clamp_gradient(None, (self._F0 - ufl.Identity(2)) * ufl.FacetNormal(p.msh))
        self.problem, self.solver = p, p.solver()
        self._boundary = np.unique(
            np.concatenate([p.component_dofs(e, i) for e in EDGE_TAGS for i in range(2)])
        )

    @classmethod
    def parse_options(cls, tables: dict, length_scale: float, where: str) -> dict:
        return {"frame": choice_option(tables, "loading", "frame", FRAMES, "pinned", where)}

    @classmethod
    def check_specimen(cls, setup: PluginSetup, where: str) -> None:
        if not math.isclose(setup.length, setup.width, rel_tol=1e-9):
            raise DataError(
                f"{where}: the picture frame is square: [specimen] length "
                f"{setup.length:g} mm and width {setup.width:g} mm differ"
            )

    @classmethod
    def default_h(cls, setup: PluginSetup) -> float:
        return setup.length / 8.0

    def set_load(self, t: float) -> None:
        F0, dF0 = frame_gradient(t, self.a)
        self._F0.value[:] = F0
        self._g.interpolate(lambda x: (F0 - np.eye(2)) @ x[:2])
        self._w.interpolate(lambda x: dF0 @ x[:2])
        keep = np.zeros(len(self._w.x.array), bool)
        keep[self._boundary] = True
        self._w.x.array[~keep] = 0.0

    def reaction_weight(self) -> fem.Function:
        return self._w
