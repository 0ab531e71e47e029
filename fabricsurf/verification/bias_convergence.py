"""Grip force of the continuum bias test under refinement on nested graded meshes
(docs/verification.md, bias extension)."""

from __future__ import annotations

import logging

from mpi4py import MPI

from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.geometry.specimen import BIAS_LENGTH, BIAS_WIDTH, Specimen, structured_rectangle
from fabricsurf.log import detail, rank0
from fabricsurf.model.terms import Term
from fabricsurf.verification.rates import richardson_summary

logger = logging.getLogger(__name__)


def graded_specimen(
    level: int,
    grading: float = 0.6,
    length: float = BIAS_LENGTH,
    width: float = BIAS_WIDTH,
    base: tuple[int, int] = (11, 7),
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> Specimen:
    """Nested graded mesh of refinement ``level``: base[0]·level × base[1]·level crossed cells
    (squares of 17 mm / level for the Barchiesi et al. 2020 specimen and the default base), refined
    towards the edges by ``grading`` (:func:`~fabricsurf.geometry.specimen.graded`): the clamp
    boundary layers and the clamp corners, where the second-gradient solution is least regular."""
    return structured_rectangle(
        length, width, base[0] * level, base[1] * level, comm, grading=grading
    )


def force_convergence(
    model: list[Term],
    levels: list[int],
    ubar: float,
    steps: int,
    grading: float = 0.6,
    length: float = BIAS_LENGTH,
    width: float = BIAS_WIDTH,
    base: tuple[int, int] = (11, 7),
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> dict:
    """Grip force at ``ubar`` on the nested graded meshes of :func:`graded_specimen`, with the
    observed rates and Richardson limit of
    :func:`~fabricsurf.verification.rates.richardson_summary` (``levels`` grow by a constant
    ratio). Returns a JSON-ready dict; scalars are reduced. Each level is logged at PROGRESS,
    its run's steps at DEBUG."""
    forces, angles = [], []
    for lev in levels:
        sp = graded_specimen(lev, grading, length, width, base, comm)
        with detail():
            r = BiasExtension(model, length, width, comm=comm, specimen=sp).run(ubar, steps)
        forces.append(r.force[-1])
        angles.append([r.angle_A_deg[-1], r.angle_B_deg[-1]])
        rank0(
            logger,
            comm,
            f"[convergence] level {lev} (cells {length / (base[0] * lev):.3g} × "
            f"{width / (base[1] * lev):.3g} mm nominal): force = "
            f"{r.force[-1]:.6f} N ({r.seconds:.1f} s)",
        )
    rs = richardson_summary(levels, forces)
    return {
        "levels": list(levels),
        "h_nominal_mm": [length / (base[0] * lev) for lev in levels],
        "grading": grading,
        "ubar": ubar,
        "force": forces,
        "angles_AB_deg": angles,
        "differences": rs["differences"],
        "rates": rs["rates"],
        "finest_error_estimate": rs["finest_error_estimate"],
        "extrapolated_force": rs["extrapolated"],
    }
