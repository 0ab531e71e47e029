"""The shear moment τ(γ) = dW/dγ of a model, derived from the terms' own densities: what the
ideal three-zone kinematics of the bias test (Cao et al. 2008 eqs. 13 and 18,
``experiments/three_zone.py``) and the picture frame ask of a shear law.

The state is the homogeneous pure shear of an inextensible net: the fibres, at their reference
angles, turn symmetrically about their bisector so that the angle between them closes by γ
(λ = μ = 1, no second gradient, no normal curvature). Its density W(γ) is each term's own UFL
``density(kin, p)`` (a term written by a user included, with its options such as γ_f of
``crossover_friction``), and τ = dW/dγ is ``ufl.derivative`` with respect to γ, exact: second-
gradient terms give 0, and so does every term that does not depend on the shear.

γ is a cellwise (DG0) field on a small ``MPI.COMM_SELF`` mesh of equal cells, one γ value per
cell, so one assembly gives τ at every γ a call asks for, the same on every rank. The form is
compiled once per model *structure* (the term classes, their options, the fibre angles): the
moduli are ``fem.Constant``\\ s assigned from the terms at every call, so fitting loops that
change moduli (``Term.set``) reuse the compiled form.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from ufl.algorithms import expand_derivatives

from fabricsurf.model.kinematics import Kinematics, fibre_vectors
from fabricsurf.model.term_constants import TermConstants


class Term(Protocol):
    """What the pure-shear evaluation reads of a term (:class:`~.term.Term`): its parameters,
    their values, one UFL parameter of each on a mesh, its shape options and its density."""

    options: tuple[str, ...]

    def parameters(self) -> list[str]: ...
    def values(self) -> dict[str, float]: ...
    def parameter_on(self, msh, name: str): ...
    def density(self, kin: Kinematics, p): ...


BIAS_ANGLES = (45.0, -45.0)
"""Fibre angles (deg from the load axis) of the bias test, the default of :func:`shear_moment`."""

_MIN_CELLS = 64
_CACHE: dict = {}
_CACHE_SIZE = 16


def strip_mesh(n: int) -> dmesh.Mesh:
    """[0, n] × [0, 1] in n × 1 squares on ``MPI.COMM_SELF``: 2n triangles of area ½, one
    state per cell, the same on every rank."""
    return dmesh.create_rectangle(
        MPI.COMM_SELF, [np.zeros(2), np.array([n, 1.0])], [n, 1], dmesh.CellType.triangle
    )


def cell_values(form: fem.FormMetaClass) -> np.ndarray:
    """The assembled cellwise (DG0) vector of ``form`` on a :func:`strip_mesh` (numpy, no PETSc
    object to destroy)."""
    return fem.assemble_vector(form).array.copy()


def pure_shear_gradient(gamma, angles: tuple[float, float]):
    """F(γ) (3×2, UFL) of the pure shear of inextensible fibres at ``angles`` (deg) that closes
    the angle between them by γ: FL = l, FM = m, unit vectors turned by ∓γ/2 towards each other
    (in the plane z = 0, so that out-of-plane terms can be evaluated too, and give 0)."""
    L, M = fibre_vectors(*angles)
    a_l, a_m = (math.radians(a) for a in angles)
    s = math.copysign(1.0, math.sin(a_l - a_m))  # L lies anticlockwise from M when s = 1
    phi_l, phi_m = a_l - s * gamma / 2, a_m + s * gamma / 2
    dual = np.linalg.inv(np.column_stack([L, M]))  # rows: the dual basis of (L, M)
    l_ = ufl.as_vector([ufl.cos(phi_l), ufl.sin(phi_l), 0.0])
    m_ = ufl.as_vector([ufl.cos(phi_m), ufl.sin(phi_m), 0.0])
    return ufl.outer(l_, ufl.as_vector(dual[0])) + ufl.outer(m_, ufl.as_vector(dual[1]))


class _Evaluator:
    """The compiled τ form of one model structure on a mesh of at least ``cells`` cells."""

    def __init__(self, model: Sequence[Term], angles: tuple[float, float], cells: int) -> None:
        n = max(_MIN_CELLS, 2 ** math.ceil(math.log2(max(cells, 1)))) // 2
        self.msh = strip_mesh(n)
        V = fem.FunctionSpace(self.msh, ("DG", 0))
        self.gamma = fem.Function(V)
        self.size = V.dofmap.index_map.size_local
        L, M = fibre_vectors(*angles)
        F = pure_shear_gradient(self.gamma, angles)
        kin = Kinematics(F, ufl.zero(3, 2, 2), ufl.as_vector(L), ufl.as_vector(M))
        self.constants = [
            TermConstants({p: t.parameter_on(self.msh, p) for p in t.parameters()}) for t in model
        ]
        W = sum((t.density(kin, c) for t, c in zip(model, self.constants)), ufl.zero())
        dx = ufl.dx(domain=self.msh, metadata={"quadrature_degree": 1})
        tau = expand_derivatives(ufl.derivative(W * dx, self.gamma, ufl.TestFunction(V)))
        # a model none of whose terms depend on γ has an empty form: τ = 0, nothing to compile
        self.form = None if tau.empty() else fem.form(tau, jit_params={"timeout": 120})

    def __call__(self, model: Sequence[Term], gamma: np.ndarray) -> np.ndarray:
        for t, c in zip(model, self.constants):
            for p, v in t.values().items():
                c.assign(p, v)
        out = np.empty(gamma.size)
        if self.form is None:
            return np.where(np.isnan(gamma), np.nan, 0.0)
        for k in range(0, gamma.size, self.size):
            chunk = gamma[k : k + self.size]
            self.gamma.x.array[:] = 0.0
            self.gamma.x.array[: chunk.size] = chunk
            out[k : k + chunk.size] = cell_values(self.form)[: chunk.size] / 0.5  # cell area ½
        return out


def structure(model: Sequence[Term], angles: tuple[float, float]) -> tuple:
    """What the compiled form depends on: each term's class and options, and the angles."""
    return (
        tuple((type(t), tuple((o, repr(getattr(t, o))) for o in t.options)) for t in model),
        tuple(float(a) for a in angles),
    )


def shear_moment(
    model: Sequence[Term], gamma, angles: tuple[float, float] = BIAS_ANGLES
) -> np.ndarray:
    """τ(γ) = dW/dγ (N/mm) of the sum of the terms of ``model`` in pure shear of inextensible
    fibres at ``angles`` (deg), at every shear angle of ``gamma`` (rad, any shape: the result
    has its shape). Round-off exact; 0 for an empty model; NaN where γ is NaN or outside
    (θ0 − π, θ0), θ0 the reference angle between the fibres (they would pass parallel)."""
    g = np.asarray(gamma, float)
    L, M = fibre_vectors(*angles)
    theta0 = math.acos(float(np.clip(L @ M, -1.0, 1.0)))
    g = np.where((g < theta0) & (g > theta0 - math.pi), g, np.nan)
    if not model:
        return np.where(np.isnan(g), np.nan, 0.0)
    key = structure(model, angles)
    ev = _CACHE.get(key)
    if ev is None or ev.size < min(g.size, 2**16):
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.clear()
        ev = _CACHE[key] = _Evaluator(model, angles, min(g.size, 2**16))
    return ev(model, g.ravel()).reshape(g.shape)
