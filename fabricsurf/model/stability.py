"""Is an energy stable where the data take the sheet? The tangent of the first-gradient density
W(λ, μ, γ) at given states (docs/usage.md, "Signed moduli and the stability check").

A coupling with a signed modulus (e.g. ½k_c γ²((λ−1)+(μ−1)) with k_c < 0) can fit the data and
still describe a material that would buckle or shear away on its own: its energy is not convex
in the strains over the states the test reached. The check: the Hessian of W with respect to
the fibre stretches and the shear angle, q = (λ, μ, γ),

    K(q) = ∂²W/∂q∂q   (3×3, N/mm: λ, μ, γ are dimensionless),

at every state of a set (the cells of a deformed specimen, and the states on the straight path
from the reference to each of them), with the second gradient held at zero. The energy is
**stable there** when no eigenvalue of K is negative beyond round-off; a zero eigenvalue is
allowed (a model without fibre stretch has no stiffness in λ, which is not an instability).

The state is the one of :func:`~fabricsurf.model.pure_shear.pure_shear_gradient` with the fibres
stretched: F = λ l ⊗ L* + μ m ⊗ M* (L*, M* the dual basis of the reference fibres), each term's
own UFL ``density(kin, p)`` differentiated twice by UFL, on a ``MPI.COMM_SELF`` strip of cells
(one state per cell, the same answer on every rank for the same states).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from ufl.algorithms import expand_derivatives

from fabricsurf.model.kinematics import Kinematics, fibre_vectors
from fabricsurf.model.pure_shear import cell_values, strip_mesh, structure
from fabricsurf.model.term_constants import TermConstants

ROUND_OFF = 1e-9
"""An eigenvalue below −ROUND_OFF × the largest |eigenvalue| over the states is negative."""
PATH_FRACTIONS = (0.25, 0.5, 0.75, 1.0)
"""Where on the straight path from the reference (λ = μ = 1, γ = 0) to each given state K is
also evaluated (a proportional load path: the states the test passed through on the way)."""
_CHUNK = 4096
_CACHE: dict = {}
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


@dataclass(frozen=True)
class TangentCheck:
    """The smallest eigenvalue of K over the states and where it sits.

    ``stable``: no eigenvalue below −ROUND_OFF × ``largest``; ``worst``: (λ, μ, γ) of the state
    with the smallest eigenvalue ``min_eigenvalue`` (N/mm); ``unstable_share``: the share of the
    states with a negative eigenvalue."""

    stable: bool
    min_eigenvalue: float
    largest: float
    worst: tuple[float, float, float]
    unstable_share: float
    states: int

    def text(self) -> str:
        lam, mu, g = self.worst
        where = f"at λ = {lam:.4g}, μ = {mu:.4g}, γ = {math.degrees(g):.3g}°"
        if self.stable:
            return (
                f"the energy is stable over the {self.states} states of the data's range "
                f"(smallest tangent eigenvalue {self.min_eigenvalue:.3g} N/mm {where})"
            )
        return (
            f"the energy is NOT stable over the data's range: the tangent ∂²W/∂(λ,μ,γ)² has "
            f"a negative eigenvalue {self.min_eigenvalue:.3g} N/mm {where} "
            f"({100 * self.unstable_share:.3g} % of {self.states} states): with these moduli "
            "the material cannot hold these strains on its own (its load path turns back or "
            "localises there)"
        )

    def as_dict(self) -> dict:
        return {
            "stable": self.stable,
            "min_eigenvalue_N_per_mm": self.min_eigenvalue,
            "largest_eigenvalue_N_per_mm": self.largest,
            "worst_state": dict(zip(("lambda", "mu", "gamma_rad"), self.worst)),
            "unstable_share": self.unstable_share,
            "states": self.states,
        }


class _Tangent:
    """The compiled Hessian entries of one model's W(λ, μ, γ) on a strip of ``n`` cells."""

    def __init__(self, model: Sequence, angles: tuple[float, float], n: int) -> None:
        self.msh = strip_mesh(n // 2)
        V = fem.FunctionSpace(self.msh, ("DG", 0))
        self.fields = [fem.Function(V) for _ in range(3)]
        q = [ufl.variable(f) for f in self.fields]
        L, M = fibre_vectors(*angles)
        a_l, a_m = (math.radians(a) for a in angles)
        s = math.copysign(1.0, math.sin(a_l - a_m))
        phi_l, phi_m = a_l - s * q[2] / 2, a_m + s * q[2] / 2
        dual = np.linalg.inv(np.column_stack([L, M]))
        l_ = ufl.as_vector([ufl.cos(phi_l), ufl.sin(phi_l), 0.0])
        m_ = ufl.as_vector([ufl.cos(phi_m), ufl.sin(phi_m), 0.0])
        F = q[0] * ufl.outer(l_, ufl.as_vector(dual[0])) + q[1] * ufl.outer(
            m_, ufl.as_vector(dual[1])
        )
        kin = Kinematics(F, ufl.zero(3, 2, 2), ufl.as_vector(L), ufl.as_vector(M))
        self.constants = [
            TermConstants({p: t.parameter_on(self.msh, p) for p in t.parameters()}) for t in model
        ]
        W = sum((t.density(kin, c) for t, c in zip(model, self.constants)), ufl.zero())
        dx = ufl.dx(domain=self.msh, metadata={"quadrature_degree": 1})
        entries = [
            expand_derivatives(ufl.diff(ufl.diff(W, q[i]), q[j])) for i, j in _PAIRS
        ]  # one form for the six entries: one compilation
        v = ufl.TestFunction(fem.VectorFunctionSpace(self.msh, ("DG", 0), dim=len(_PAIRS)))
        self.form = fem.form(sum(e * v[k] for k, e in enumerate(entries)) * dx)
        self.size = V.dofmap.index_map.size_local

    def __call__(self, model: Sequence, states: np.ndarray) -> np.ndarray:
        """K at every state (n×3 → n×3×3)."""
        for t, c in zip(model, self.constants):
            for p, v in t.values().items():
                c.assign(p, v)
        K = np.zeros((len(states), 3, 3))
        for k in range(0, len(states), self.size):
            chunk = states[k : k + self.size]
            for f, col in zip(self.fields, chunk.T):
                f.x.array[:] = 1.0 if f is not self.fields[2] else 0.0
                f.x.array[: len(col)] = col
            values = cell_values(self.form).reshape(-1, len(_PAIRS))[: len(chunk)] / 0.5
            for k_, (i, j) in enumerate(_PAIRS):  # cell area ½
                K[k : k + len(chunk), i, j] = K[k : k + len(chunk), j, i] = values[:, k_]
        return K


def path_states(states: np.ndarray) -> np.ndarray:
    """``states`` (n×3: λ, μ, γ) and the states at :data:`PATH_FRACTIONS` of the straight path
    from the reference to each."""
    ref = np.array([1.0, 1.0, 0.0])
    states = np.asarray(states, float).reshape(-1, 3)
    return np.vstack([ref + t * (states - ref) for t in PATH_FRACTIONS])


def check_tangent(
    model: Sequence, angles: tuple[float, float], states: np.ndarray, comm=None
) -> TangentCheck:
    """:class:`TangentCheck` of the first-gradient energy of ``model`` (terms with their moduli)
    at fibre ``angles`` (deg) over ``states`` (n×3: λ, μ, γ in rad; each rank its own, and
    with ``comm`` the answer reduced over all ranks' states)."""
    states = np.asarray(states, float).reshape(-1, 3)
    states = states[np.isfinite(states).all(1)]
    key = structure(model, angles)
    if key not in _CACHE:
        _CACHE.clear()  # one model structure at a time: a fit checks one model
        _CACHE[key] = _Tangent(model, angles, _CHUNK)
    tangent = _CACHE[key]
    eig = np.linalg.eigvalsh(tangent(model, states)) if len(states) else np.zeros((0, 3))
    low = eig[:, 0] if len(eig) else np.array([np.inf])
    k = int(np.argmin(low))
    local = (float(low[k]), states[k].tolist() if len(states) else [1.0, 1.0, 0.0])
    largest = float(np.max(np.abs(eig))) if len(eig) else 0.0
    n = len(states)
    if comm is not None and comm.size > 1:
        local = min(comm.allgather(local), key=lambda t: t[0])
        largest, n = comm.allreduce(largest, op=MPI.MAX), comm.allreduce(n)
    bound = -ROUND_OFF * largest
    negative = int(np.count_nonzero(low < bound)) if len(eig) else 0
    if comm is not None and comm.size > 1:
        negative = comm.allreduce(negative)
    return TangentCheck(
        stable=local[0] >= bound,
        min_eigenvalue=local[0] if math.isfinite(local[0]) else 0.0,
        largest=largest,
        worst=tuple(local[1]),
        unstable_share=negative / max(n, 1),
        states=n,
    )
