"""Manufactured solutions for the discrete second-gradient energy (the C0-IP rung of
docs/verification.md).

For an exact displacement u_e (a UFL expression of X), the load is ℓ(v) = R_h(u_e)[v]: the
discrete residual evaluated at u_e. Because u_e is smooth its gradient jumps vanish, so ℓ is the
weak form of the exact body force and edge loads of the continuous problem, and u_e its exact
solution; the discrete solution of R_h(u_h) = ℓ with u_h = u_e and ∂_n u_h = ∂_n u_e on ∂Ω then
measures the discretisation error alone.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import ufl
from dolfinx import fem

from fabricsurf.discretise.energy import EVERYWHERE, EnergyForm
from fabricsurf.discretise.problem import boundary_facets
from fabricsurf.discretise.solver import SNESSolver
from fabricsurf.geometry.specimen import structured_rectangle
from fabricsurf.model.terms import Term


def norms(e, msh, qdeg: int = 6) -> dict[str, float]:
    """L2 norm, H1 seminorm and broken H2 seminorm of e (reduced over ranks)."""
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": qdeg})
    out = {}
    for name, q in (("L2", e), ("H1", ufl.grad(e)), ("H2", ufl.grad(ufl.grad(e)))):
        local = fem.assemble_scalar(fem.form(ufl.inner(q, q) * dx))
        out[name] = float(np.sqrt(msh.comm.allreduce(local)))
    return out


def manufactured_solve(
    model: list[Term],
    u_exact: Callable,
    n: int,
    d: int,
    angles: tuple[float, float] = (30.0, -60.0),
    penalty: float = 8.0,
    comm=None,
) -> tuple[dict[str, float], int]:
    """Solve the manufactured problem on a structured n×n unit square; return the error norms of
    u_h − u_e and the Newton iterations."""
    from mpi4py import MPI

    from fabricsurf.model.kinematics import fibre_directions

    sp = structured_rectangle(1.0, 1.0, n, n, comm or MPI.COMM_WORLD)
    msh = sp.mesh
    V = fem.VectorFunctionSpace(msh, ("CG", 2), dim=d)
    u = fem.Function(V)
    x = ufl.SpatialCoordinate(msh)
    ue = u_exact(x)
    nrm = ufl.FacetNormal(msh)
    L, M = fibre_directions(*angles)
    E = EnergyForm(
        model,
        u,
        L,
        M,
        sp.facet_tags,
        normal_derivative={EVERYWHERE: ufl.grad(ue) * nrm},
        penalty=penalty,
    )
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    R = E.residual(v)
    load = ufl.replace(R, {u: ue})
    g = fem.Function(V)
    g.interpolate(fem.Expression(ue, V.element.interpolation_points()))
    bc = fem.dirichletbc(g, fem.locate_dofs_topological(V, 1, boundary_facets(msh)))
    # meshes of at most a few thousand cells: compiling the kernels costs more than running them
    solver = SNESSolver(
        R - load,
        E.jacobian(du, v),
        u,
        [bc],
        prefix=f"fabricsurf_mms{d}_",
        options={"compile": "fast"},
    )
    reason, its = solver.solve()
    if reason <= 0:
        raise RuntimeError(f"manufactured problem (n = {n}, d = {d}) did not converge: {reason}")
    return norms(u - ue, msh), its


def in_plane_model() -> list[Term]:
    """All in-plane terms with distinct moduli (the 2D manufactured case)."""
    from fabricsurf.model.terms import (
        FibreStretch,
        GeodesicBending,
        Shear,
        ShearGradient,
        StretchGradient,
    )

    return [
        FibreStretch(k_l=1.0, k_m=2.0),
        Shear(k_s=1.0),
        GeodesicBending(A_g=1.0),
        StretchGradient(A_s=0.5),
        ShearGradient(A_Gamma=0.7),
    ]


def full_3d_model() -> list[Term]:
    """The in-plane terms with normal bending and twist (the 3D manufactured case)."""
    from fabricsurf.model.terms import NormalBending, Twist

    return in_plane_model() + [NormalBending(k_b=1.0), Twist(k_t=0.8)]


def u_2d(x):
    """A smooth in-plane displacement of the unit square."""
    return 0.1 * ufl.as_vector((ufl.sin(2 * x[0] + x[1]), ufl.cos(x[0] - 2 * x[1])))


def u_3d(x):
    """A smooth displacement with an out-of-plane bulge."""
    return ufl.as_vector(
        (
            0.1 * ufl.sin(2 * x[0] + x[1]),
            0.1 * ufl.cos(x[0] - 2 * x[1]),
            0.2 * ufl.sin(ufl.pi * x[0]) * ufl.sin(ufl.pi * x[1]),
        )
    )
