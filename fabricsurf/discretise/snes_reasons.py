"""PETSc's SNES converged reasons in words (for messages and logs)."""

from __future__ import annotations

from petsc4py import PETSc

RELATIVE = int(PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE)
"""The reason of a solve accepted by the relative residual test alone (``snes_rtol``)."""


def _reason_names() -> dict[int, str]:
    R = PETSc.SNES.ConvergedReason
    names = {getattr(R, k): k for k in dir(R) if k.isupper() and k != "ITERATING"}
    names[0] = "CONVERGED_ITERATING"
    return names


SNES_REASONS = _reason_names()


def reason_name(reason: int) -> str:
    """PETSc's SNESConvergedReason code in words, e.g. −5 → 'DIVERGED_MAX_IT (-5)'."""
    return f"{SNES_REASONS.get(int(reason), 'UNKNOWN')} ({int(reason)})"
