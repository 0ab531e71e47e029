"""Exact sensitivities of a converged forward state to the moduli (forward.py's docstring).

Π_h is linear in the vector of moduli p, so ∂R/∂p_k is the assembled residual with that
modulus 1 and all others 0 (minus R(0) where a part of R no modulus multiplies: the tools'
contact), and du/dp_k = −K⁻¹ ∂R/∂p_k is solved with the converged Jacobian's factorisation.
The reaction R·w then has the sensitivity (∂R/∂p + K du/dp)·w; a reaction functional F(u) of
its own (the hemisphere's punch force) ∂F/∂p + (∂F/∂u)·du/dp.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc

from fabricsurf.discretise.resources import copy_to_function, destroy, dot_function


def at_moduli(fm, vals: np.ndarray, evaluate):
    """``evaluate()`` with the moduli of forward model ``fm`` set to ``vals`` (restored
    after)."""
    old = fm.values()
    fm.set_values(vals)
    try:
        return evaluate()
    finally:
        fm.set_values(old)


def _unit(fm, k: int) -> np.ndarray:
    return np.eye(len(fm.params))[k]


def dR_dp(fm, k: int) -> PETSc.Vec:
    """R(e_k) at the current u (no boundary conditions), in the solver's work vector: ∂R/∂p_k
    when no part of R is free of the moduli (else minus R(0), :func:`sensitivities`)."""
    return at_moduli(fm, _unit(fm, k), fm.test.solver.internal_force)


def sensitivities(fm, which: list[int], w) -> list[tuple[fem.Function, float]]:
    """(du/dp_k, dF/dp_k) for k in ``which`` at the converged state of ``fm``: the reaction
    R·w (``w``) or the test's reaction functional F (module docstring)."""
    s, obs = fm.test.solver, fm.observers
    ksp = s.snes.getKSP()
    A_full = fem_petsc.assemble_matrix(s.a)
    A_full.assemble()
    out, x, Kdu = [], s.x.duplicate(), s.x.duplicate()
    zero = np.zeros(len(fm.params))
    affine = fm.affine and which
    r0 = at_moduli(fm, zero, s.internal_force).copy() if affine else None
    dFdu = obs.force_gradient() if obs.reaction is not None and which else None
    F0 = at_moduli(fm, zero, obs.force) if dFdu is not None else 0.0
    for k in which:
        b = dR_dp(fm, k)
        if r0 is not None:
            b.axpy(-1.0, r0)
        dF = dot_function(b, w) if w is not None else 0.0
        b.scale(-1.0)
        with b.localForm() as loc:
            loc.array[fm.bc_dofs] = 0.0
        ksp.solve(b, x)
        if w is not None:
            A_full.mult(x, Kdu)
            dF += dot_function(Kdu, w)
        if dFdu is not None:
            dF += at_moduli(fm, _unit(fm, k), obs.force) - F0 + dFdu.dot(x)
        du = fem.Function(fm.test.problem.V)
        copy_to_function(x, du)
        out.append((du, dF))
    destroy(A_full, x, Kdu, r0, dFdu)
    return out
