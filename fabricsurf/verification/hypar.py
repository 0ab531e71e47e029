"""The hyperbolic-paraboloid exact solution of the fabric-surface theory (Steigmann & dell'Isola
2015 §5).

r(θ) = a θ1θ2 + b θ1 + c θ2 + d on the unit square, fibres along θ1 (L = e1) and θ2 (M = e2),
w = w1(λ) + w2(μ) (``fibre_stretch`` only, no shear), A_Γ = k̄ (``shear_gradient`` and
``twist`` moduli equal), any ``geodesic_bending``, ``stretch_gradient``, ``normal_bending``.
Then g_l = g_m = 0, K_L = K_M = 0, Γ + Tn = a (eqs. 101-102), M^{αβ} = ½A_Γ(L^αM^β+M^αL^β)a
(eq. 103) is uniform, T^α = N^α = w_λL^αl + w_μM^αm (eq. 105) and T^α_{|α} = 0 (eq. 106).
Edge loads (eq. 94): traction t = N^α ν_α (= ±w_λ l on θ1 = const, ±w_μ m on θ2 = const), no
edge double force, and corner forces f = −[M^{αβ}ν_ατ_β] = ±A_Γ a: + at (0,0) and (1,1), − at
(1,0) and (0,1) (τ = N×ν, the boundary traversed anticlockwise).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.evaluation import eval_points, interpolate_expression
from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.discretise.stepping import LoadStepper
from fabricsurf.model import kinematics as kn
from fabricsurf.model.terms import (
    FibreStretch,
    GeodesicBending,
    NormalBending,
    ShearGradient,
    StretchGradient,
    Term,
    Twist,
)

CORNER_SIGNS = {(0.0, 0.0): 1.0, (1.0, 0.0): -1.0, (1.0, 1.0): 1.0, (0.0, 1.0): -1.0}
PINNED = ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0))


@dataclass
class Hypar:
    """Data of the exact solution; ``k_t`` may differ from ``A_Gamma`` for the counter-check."""

    a: np.ndarray = field(default_factory=lambda: np.array([0.05, 0.05, 0.3]))
    b: np.ndarray = field(default_factory=lambda: np.array([1.05, 0.0, 0.0]))
    c: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.05, 0.0]))
    k: float = 10.0
    A_Gamma: float = 1.0
    k_t: float = 1.0
    A_g: float = 0.5
    A_s: float = 0.5
    k_b: float = 1.0

    def model(self) -> list[Term]:
        return [
            FibreStretch(k_l=self.k, k_m=self.k),
            ShearGradient(A_Gamma=self.A_Gamma),
            Twist(k_t=self.k_t),
            GeodesicBending(A_g=self.A_g),
            StretchGradient(A_s=self.A_s),
            NormalBending(k_b=self.k_b),
        ]

    def placement(self, x):
        """r(θ) as a UFL expression (d = 0)."""
        a, b, c = (ufl.as_vector(list(v)) for v in (self.a, self.b, self.c))
        return a * x[0] * x[1] + b * x[0] + c * x[1]

    def displacement(self, x):
        return self.placement(x) - ufl.as_vector([x[0], x[1], 0.0])

    def displacement_np(self, X: np.ndarray) -> np.ndarray:
        """u at points X (n×2)."""
        r = (
            np.outer(X[:, 0] * X[:, 1], self.a)
            + np.outer(X[:, 0], self.b)
            + np.outer(X[:, 1], self.c)
        )
        r[:, :2] -= X
        return r

    def traction(self, x, nu):
        """t = N^α ν_α = w_λ (L·ν) l + w_μ (M·ν) m from the exact solution (eqs. 94, 105)."""
        F = ufl.grad(self.placement(x))
        L, M = kn.fibre_directions(0.0, 90.0)
        w_lam = self.k * (kn.lam(F, L) - 1)
        w_mu = self.k * (kn.mu(F, M) - 1)
        return w_lam * ufl.dot(L, nu) * kn.l_dir(F, L) + w_mu * ufl.dot(M, nu) * kn.m_dir(F, M)

    def corner_force(self, corner) -> np.ndarray:
        return CORNER_SIGNS[tuple(corner)] * self.A_Gamma * self.a


def loaded_problem(specimen, hyp: Hypar, prefix: str) -> tuple[FabricProblem, Callable]:
    """The problem with the edge tractions and corner forces of the exact solution as dead
    loads, scaled by a factor s; returns it and ``set_load(s)``."""
    p = FabricProblem(
        specimen, hyp.model(), d=3, fibre_angles=(0.0, 90.0), prefix=prefix, snes_options=TIGHT
    )
    x = ufl.SpatialCoordinate(p.msh)
    s = fem.Constant(p.msh, 0.0)
    nu = ufl.FacetNormal(p.msh)
    for edge in specimen.edge_tags:
        p.add_traction(edge, s * hyp.traction(x, nu))
    corner_f = {}
    for corner in CORNER_SIGNS:
        corner_f[corner] = fem.Constant(p.msh, np.zeros(3))
        p.add_point_force(corner, corner_f[corner])

    def set_load(t: float) -> None:
        s.value = t
        for corner, c in corner_f.items():
            c.value[:] = t * hyp.corner_force(corner)

    return p, set_load


def solve_dirichlet(specimen, hyp: Hypar) -> tuple[FabricProblem, float]:
    """u prescribed on the whole boundary, ∂_n u free; returns the max nodal error.

    The hypar's edge double force vanishes (M_nn = 0 by eq. 103: M^{αβ} has only the mixed
    components), so the natural condition on ∂_n u holds and the quadratic placement, which
    is in the discrete space, solves the discrete problem. The loads of the natural case act
    on fixed nodes only; they are kept (at zero) so that both cases compile the same forms.
    """
    p, _ = loaded_problem(specimen, hyp, "fabricsurf_hypar_dirichlet_")
    g = fem.Function(p.V)
    g.interpolate(
        fem.Expression(
            hyp.displacement(ufl.SpatialCoordinate(p.msh)), p.V.element.interpolation_points()
        )
    )
    for edge in specimen.edge_tags:
        p.fix_function(edge, g)
    reason, _ = p.solve()
    if reason <= 0:
        raise RuntimeError(f"hypar Dirichlet case: SNES diverged (reason {reason})")
    err = np.abs(p.u.x.array - g.x.array).max(initial=0.0)
    return p, float(p.msh.comm.allreduce(err, op=MPI.MAX))


TIGHT = {"snes_rtol": 1e-14, "snes_atol": 1e-12, "compile": "fast"}
"""Newton to round-off; the meshes are tiny, so unoptimised kernels (compiled in a third of
the time) cost nothing."""


def solve_natural(specimen, hyp: Hypar, steps: int = 3) -> FabricProblem:
    """Edge tractions and corner forces from the exact solution as dead loads; three corners
    pinned at their exact positions (rigid motions and the two zero-energy mechanisms of a
    shear-free net — rotations of b and c about a — removed). Load-stepped in a factor s."""
    p, set_forces = loaded_problem(specimen, hyp, "fabricsurf_hypar_natural_")
    exact = {pt: hyp.displacement_np(np.array([pt]))[0] for pt in PINNED}
    pins = {pt: p.fix_point(pt, np.zeros(3)) for pt in PINNED}

    def set_load(t: float) -> None:
        set_forces(t)
        for pt, consts in pins.items():
            for i, c in enumerate(consts):
                c.value = t * exact[pt][i]

    LoadStepper(p.solver(), set_load).run(np.linspace(1.0 / steps, 1.0, steps))
    return p


def l2_error(p: FabricProblem, hyp: Hypar, qdeg: int = 6) -> float:
    x = ufl.SpatialCoordinate(p.msh)
    e = p.u - hyp.displacement(x)
    dx = ufl.Measure("dx", domain=p.msh, metadata={"quadrature_degree": qdeg})
    return float(np.sqrt(p.msh.comm.allreduce(fem.assemble_scalar(fem.form(ufl.inner(e, e) * dx)))))


def computed_corner_forces(p: FabricProblem) -> dict:
    """f = −[M^{αβ}ν_ατ_β] (eq. 94) from the computed double force at each corner: with ν, τ
    along ±e1, ±e2 it is ±(M[:,0,1] + M[:,1,0]) with the signs of CORNER_SIGNS."""
    Mt = p.energy.double_force()
    q = ufl.as_vector([Mt[i, 0, 1] + Mt[i, 1, 0] for i in range(3)])
    qh = interpolate_expression(q, fem.VectorFunctionSpace(p.msh, ("DG", 1), dim=3))
    pts = np.array(list(CORNER_SIGNS))
    vals = eval_points(qh, pts)
    return {c: CORNER_SIGNS[c] * vals[k] for k, c in enumerate(CORNER_SIGNS)}
