"""The planar bias-extension test with the continuum model (Barchiesi et al. 2020 §2, eq. 7;
docs/theory.md). Specimen [0, length] × [0, width] (mm), fibres at ±45° to the load (x).
Clamps of Barchiesi et al. 2020 eq. (7): u = 0 at x = 0 and u = ū e_x at x = length, with zero
normal derivative on both (weakly, by Nitsche) when the model has second-gradient terms. The
reaction is the virtual work of the residual at the grip; shear angles are evaluated at A and B
of Barchiesi et al. 2020 Fig. 4 (A: where the fibre lines from the clamp's corners cross, at
±45°; B: the centre). The test as an experiment plug-in, for compare, fit and diagnose, is
:class:`~fabricsurf.experiments.bias_plugin.BiasExtensionPlugin`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.energy import has_second_gradient
from fabricsurf.discretise.evaluation import (
    eval_points,
    interpolate_expression,
    max_over_cells,
    quadrature_expression,
)
from fabricsurf.discretise.output import FieldWriter, StepLog, write_json
from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.discretise.stepping import LoadStepError, LoadStepper
from fabricsurf.experiments.bias_mesh import (
    announce,
    check_bias_angles,
    choose_fibre_treatment,
    specimen_mesh,
)
from fabricsurf.experiments.followers import step_followers
from fabricsurf.geometry.aligned import canonical_angles
from fabricsurf.geometry.specimen import Specimen, bias_points
from fabricsurf.log import rank0
from fabricsurf.model.terms import FibreStretch, GeodesicBending, Shear, Term

logger = logging.getLogger(__name__)
CLAMPS = ("gradient", "position")


def default_model() -> list[Term]:
    """fibre_stretch + shear + geodesic_bending with moduli of a stiff-fibre, soft-pivot fabric
    (N/mm, N/mm, N·mm)."""
    return [FibreStretch(k_l=30.0, k_m=30.0), Shear(k_s=0.5), GeodesicBending(A_g=40.0)]


@dataclass
class BiasResult:
    """Per-step results (scalars reduced over ranks)."""

    ubar: list = field(default_factory=list)
    force: list = field(default_factory=list)
    angle_A_deg: list = field(default_factory=list)
    angle_B_deg: list = field(default_factory=list)
    newton: list = field(default_factory=list)
    tension_max: list = field(default_factory=list)
    seconds: float = 0.0
    discretisation: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items()}


class BiasExtension:
    """Set-up and load stepping of the continuum bias-extension test.

    The mesh is :func:`specimen_mesh` of size ``h`` and kind ``mesh``: by default fibre-aligned
    when the fibres are at ±θ to the load (corner to corner where a lattice fits, else a
    lattice from each grip; no intra-ply shear locking, so nearly inextensible yarns need no
    fine mesh; docs/theory.md), else gmsh's unstructured one. A ``specimen`` (e.g. a graded
    :func:`~fabricsurf.geometry.specimen.structured_rectangle`) replaces it; its edges must
    carry the ``clamp`` / ``grip`` tags, and ``length``, ``width``, ``h``, ``mesh`` are then
    unused (A and B follow ``specimen.length`` and ``specimen.width``).

    :attr:`model` holds the test's own copies of the terms given (``Term.copy``):
    ``test.model[i].set(...)`` changes it (without recompiling), the terms given do not.

    ``followers`` are called after each converged step of :meth:`run`: by default those the
    model's terms need (:func:`~fabricsurf.experiments.followers.step_followers`, e.g. the
    interior penalty of the bi-pantographic energy following the stretch); replace the list to
    change them (an empty list freezes those parameters).

    ``fibre_treatment`` (:data:`~fabricsurf.experiments.bias_mesh.TREATMENTS`): ``auto``
    integrates the fibre terms fully. The mesh and treatment used, and whether the answer may
    be locked, are logged before computing (:func:`~fabricsurf.experiments.bias_mesh.announce`)
    and recorded in :attr:`discretisation` and the result.
    """

    def __init__(
        self,
        model: list[Term] | None = None,
        length: float = 187.0,
        width: float = 119.0,
        h: float = 8.0,
        clamp: str = "gradient",
        fibre_angles: tuple[float, float] = (45.0, -45.0),
        snes_options=None,
        comm: MPI.Comm = MPI.COMM_WORLD,
        specimen: Specimen | None = None,
        mesh: str = "auto",
        fibre_treatment: str = "auto",
    ) -> None:
        if clamp not in CLAMPS:
            raise ValueError(f"clamp = {clamp!r}: must be 'gradient' or 'position'")
        self.model = (
            [t.copy() for t in model]
            if model is not None  # its own terms
            else default_model()
        )
        given = tuple(float(a) for a in fibre_angles)
        fibre_angles = canonical_angles(given)
        if specimen is None:
            check_bias_angles(fibre_angles, length, width)
        self.specimen = (
            specimen
            if specimen is not None
            else specimen_mesh(length, width, h, fibre_angles, comm, mesh, self.model)
        )
        self.discretisation = choose_fibre_treatment(
            fibre_treatment, self.specimen, self.model, h, given, fibre_angles
        )
        announce(comm, self.discretisation)
        p = FabricProblem(
            self.specimen,
            self.model,
            d=2,
            fibre_angles=fibre_angles,
            snes_options=snes_options,
            prefix="fabricsurf_bias_",
            fibre_treatment=self.discretisation["fibre_treatment"],
        )
        p.fix("clamp", (0.0, 0.0))
        self.grip_ux, _ = p.fix("grip", (0.0, 0.0))
        if clamp == "gradient" and has_second_gradient(self.model):
            p.clamp_gradient("clamp")
            p.clamp_gradient("grip")
        self.problem = p
        self.solver = p.solver()
        self.followers = step_followers(p, self.model)
        kin = p.energy.kin
        self._fibre_V = fem.VectorFunctionSpace(p.msh, ("DG", 2), dim=3)
        self._fibre_expr = ufl.as_vector([kin.lam, kin.mu, kin.gamma])
        self._tensions = [
            quadrature_expression(e, p.msh, p.energy.tension_degree)
            for e in p.energy.tension_fields().values()
        ]
        pts = {**bias_points(self.specimen.length, self.specimen.width), **self.specimen.points}
        self.points = np.array([pts["A"], pts["B"]])

    def set_load(self, ubar: float) -> None:
        self.grip_ux.value = ubar

    def tension_max(self) -> float:
        """The largest fibre tension of either family (N/mm, at the quadrature points; the
        multipliers for exact inextensibility), reduced over ranks; NaN without fibre terms."""
        if not self._tensions:
            return float("nan")
        return max(max_over_cells(e, self.problem.msh) for e in self._tensions)

    def angles_deg(self) -> np.ndarray:
        """Shear angles γ at A and B (:attr:`points`) in degrees."""
        return np.degrees(self.fibre_fields_at(self.points)[:, 2])

    def displacement_at(self, points: np.ndarray) -> np.ndarray:
        """The continuum displacement u (P2) at reference points (n×2), (n×2) on every rank."""
        return eval_points(self.problem.u, points)

    def fibre_fields_at(self, points: np.ndarray) -> np.ndarray:
        """(λ, μ, γ) at reference points (n×3, γ in rad), the same on every rank."""
        f = interpolate_expression(self._fibre_expr, self._fibre_V)
        return eval_points(f, points)

    def run(
        self,
        ubar_max: float,
        steps: int,
        out: Path | None = None,
        on_step: Callable[[int, float], None] | None = None,
    ) -> BiasResult:
        """Load to ``ubar_max`` in ``steps`` equal requested steps; write XDMF/logs to ``out``;
        each converged step is logged at PROGRESS (its increments' cuts at DEBUG).

        After each converged requested step the :attr:`followers` are called, then
        ``on_step(k, ubar)`` on every rank (e.g. to sample :meth:`displacement_at`); collective
        calls are allowed there. A step that fails raises :class:`LoadStepError` with the
        converged steps as its ``partial``.
        """
        comm = self.problem.msh.comm
        res, t0 = BiasResult(discretisation=dict(self.discretisation)), time.perf_counter()
        energy = self.problem.energy
        writer = (
            FieldWriter(
                Path(out) / "bias.xdmf",
                self.problem.u,
                energy.kin,
                _writer_degree(energy),
                energy.tension_fields(),
            )
            if out
            else None
        )
        log = StepLog(comm, Path(out), "bias_steps") if out else None

        def converged(k: int, ubar: float, its: int) -> None:
            f = self.problem.reaction("grip", 0)
            a = self.angles_deg()
            t_max = self.tension_max()
            for lst, v in (
                (res.ubar, ubar),
                (res.force, f),
                (res.angle_A_deg, a[0]),
                (res.angle_B_deg, a[1]),
                (res.newton, its),
                (res.tension_max, t_max),
            ):
                lst.append(float(v))
            if writer:
                writer.write(ubar)
                log.add(
                    step=k + 1,
                    ubar=ubar,
                    force=f,
                    angle_A_deg=a[0],
                    angle_B_deg=a[1],
                    tension_max=t_max,
                    newton_iterations=its,
                )
            rank0(
                logger,
                comm,
                f"  step {k + 1}/{steps}: ubar = {ubar:7.3f} mm  force = "
                f"{f:9.4f} N  gamma_A = {a[0]:6.2f} deg  gamma_B = {a[1]:6.2f} deg"
                f"  max fibre tension {t_max:8.4g} N/mm  Newton {its}",
            )
            for follow in self.followers:
                follow()
            if on_step is not None:
                on_step(k, ubar)

        stepper = LoadStepper(self.solver, self.set_load, converged, label="  ")
        try:
            stepper.run(np.linspace(ubar_max / steps, ubar_max, steps))
        except LoadStepError as e:  # with the converged steps
            hint = f"{e}. {EXACT_FIBRES_HINT}" if energy.multipliers else None
            raise e.carrying(hint, partial=res) from e
        finally:
            res.seconds = time.perf_counter() - t0
            if writer:
                writer.close()
            if out:
                write_json(comm, Path(out) / "bias_curve.json", res.as_dict())
        return res


EXACT_FIBRES_HINT = (
    "With inextensible fibres a step also fails where no inextensible deformation of the net "
    "reaches the grip displacement: past the net's kinematic limit (300 x 130 mm at +-30 deg "
    "stops at ubar = 0.0386 L; the force of elastic fibres at K/k_s = 1e9 is 13 N at 0.035 L "
    "and 1e5 N at 0.04 L, on h = W/10 and W/20 alike), or on a mesh that locks (see the mesh "
    "notice). To tell which, "
    "run elastic fibres at two K/k_s (1e6, 1e9) and h and h/2: a force that grows with K on "
    "both meshes is the kinematic limit"
)
"""Appended to a failed load step's message when the fibres are exactly inextensible
(docs/theory.md, "Exact inextensibility")."""


def _writer_degree(energy) -> int:
    """The quadrature degree of the XDMF projections: that of the fibre tensions when they
    are not the full cell degree's (reduced fibre terms) or live in a quadrature space
    (multipliers), else 2."""
    if energy.reduced or energy.multipliers:
        return energy.tension_degree
    return 2
