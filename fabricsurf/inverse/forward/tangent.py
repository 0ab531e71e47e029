"""Exact sensitivities of a converged forward state to the moduli (forward.py's docstring).

Π_h is linear in the vector of moduli p, so ∂R/∂p_k is the assembled residual with that
modulus 1 and all others 0 (minus R(0) where a part of R no modulus multiplies: the tools'
contact), and du/dp_k = −K⁻¹ ∂R/∂p_k is solved with the converged Jacobian's factorisation.
The reaction R·w then has the sensitivity (∂R/∂p + K du/dp)·w; a reaction functional F(u) of
its own (the hemisphere's punch force) ∂F/∂p + (∂F/∂u)·du/dp.

K du/dp·w needs the rows of the full K (no boundary conditions) at the reaction's weight w.
Where w lies on the prescribed dofs B only (a grip's motion), du/dp vanishes on B and K is
symmetric (the Hessian of Π_h, solved by the plain
:class:`~fabricsurf.discretise.solver.SNESSolver`, not by a subclass with a history such as
the forming plug-in's friction), so (K du)·w = du·(K w) with K w = K[:, B] w_B: the Dirichlet
lifting of w (:func:`_lifted_weight`), assembled on the cells at B only, once per step,
instead of a new matrix of the full Jacobian. Any other w (or :data:`SYMMETRIC` off) takes
the full matrix.
"""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabricsurf.discretise.resources import copy_to_function, destroy, dot_function
from fabricsurf.discretise.solver import SNESSolver

SYMMETRIC = True
"""Whether the reaction's sensitivity may use K's symmetry (module docstring; False: the full
matrix at every step, as before, for comparisons)."""


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


def _on_prescribed(fm, w) -> bool:
    """Whether the weight ``w`` is zero off the prescribed dofs, on every rank."""
    off = np.ones(len(w.x.array), bool)
    off[fm.bc_dofs] = False
    mine = not np.any(w.x.array[off])
    return bool(fm.test.solver.comm.allreduce(mine, op=MPI.LAND))


def _lifted_weight(s, w) -> PETSc.Vec:
    """K[:, B] w_B at the converged state (module docstring): the lifting SNES's residual
    applies, b + K (g − x0), with x0 = u − w, since u = g on the prescribed dofs B (the caller
    destroys it)."""
    y, x0 = s.x.duplicate(), s.x.duplicate()
    with x0.localForm() as loc:
        loc.array[:] = s.u.x.array - w.x.array
    with y.localForm() as loc:
        loc.set(0.0)
    fem_petsc.apply_lifting(y, [s.forms()[1]], bcs=[s.bcs], x0=[x0], scale=-1.0)
    y.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    destroy(x0)
    return y


def sensitivities(fm, which: list[int], w, start=None) -> list[tuple[fem.Function, float]]:
    """(du/dp_k, dF/dp_k) for k in ``which`` at the converged state of ``fm``: the reaction
    R·w (``w``) or the test's reaction functional F (module docstring). ``start``: du_n/dp_k
    of the state the step started from, for a solver whose residual depends on it (path.py),
    adding (∂R/∂u_n)·du_n/dp_k to ∂R/∂p_k and (∂F/∂u_n)·du_n/dp_k to dF/dp_k. A solver whose
    Newton Jacobian leaves a term out (the forming tools' curvature) gives the exact one here
    (``exact_tangent``)."""
    exact = getattr(fm.test.solver, "exact_tangent", None)
    with exact() if exact is not None else nullcontext():
        return _sensitivities(fm, which, w, start)


def _sensitivities(fm, which: list[int], w, start) -> list[tuple[fem.Function, float]]:
    s, obs = fm.test.solver, fm.observers
    ksp = s.snes.getKSP()
    A_full = Kw = None
    if w is not None and which:
        if SYMMETRIC and type(s) is SNESSolver and _on_prescribed(fm, w):
            Kw = _lifted_weight(s, w)
        else:
            A_full = fem_petsc.create_matrix(s.a, s.matrix_type)
            fem_petsc.assemble_matrix(A_full, s.a)
            A_full.assemble()
    out, x, Kdu = [], s.x.duplicate(), s.x.duplicate()
    zero = np.zeros(len(fm.params))
    affine = fm.affine and which
    r0 = at_moduli(fm, zero, s.internal_force).copy() if affine else None
    dFdu = obs.force_gradient() if obs.reaction is not None and which else None
    F0 = at_moduli(fm, zero, obs.force) if dFdu is not None else 0.0
    dFdu_n = obs.force_history_gradient() if dFdu is not None and start else None
    for j, k in enumerate(which):
        b = dR_dp(fm, k)
        if r0 is not None:
            b.axpy(-1.0, r0)
        if start:
            h = s.path_action(start[j])
            b.axpy(1.0, h)
            destroy(h)
        dF = dot_function(b, w) if w is not None else 0.0
        if dFdu_n is not None:
            dF += dot_function(dFdu_n, start[j])
        b.scale(-1.0)
        with b.localForm() as loc:
            loc.array[fm.bc_dofs] = 0.0
        ksp.solve(b, x)
        if Kw is not None:
            dF += Kw.dot(x)
        elif w is not None:
            A_full.mult(x, Kdu)
            dF += dot_function(Kdu, w)
        if dFdu is not None:
            dF += at_moduli(fm, _unit(fm, k), obs.force) - F0 + dFdu.dot(x)
        du = fem.Function(fm.test.problem.V)
        copy_to_function(x, du)
        out.append((du, dF))
    destroy(A_full, Kw, x, Kdu, r0, dFdu, dFdu_n)
    return out
