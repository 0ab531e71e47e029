"""Manufactured solutions for the discrete second-gradient energy (verification ladder rung 2).

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

from fabricsurf.energy import EnergyForm
from fabricsurf.problem import boundary_facets
from fabricsurf.solver import SNESSolver
from fabricsurf.terms import Term
from geometry.specimen import EDGE_TAGS, structured_rectangle


def norms(e, msh, qdeg: int = 6) -> dict[str, float]:
    """L2 norm, H1 seminorm and broken H2 seminorm of e (reduced over ranks)."""
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": qdeg})
    out = {}
    for name, q in (("L2", e), ("H1", ufl.grad(e)), ("H2", ufl.grad(ufl.grad(e)))):
        local = fem.assemble_scalar(fem.form(ufl.inner(q, q) * dx))
        out[name] = float(np.sqrt(msh.comm.allreduce(local)))
    return out


def manufactured_solve(model: list[Term], u_exact: Callable, n: int, d: int,
                       angles: tuple[float, float] = (30.0, -60.0), penalty: float = 8.0,
                       comm=None) -> tuple[dict[str, float], int]:
    """Solve the manufactured problem on a structured n×n unit square; return the error norms of
    u_h − u_e and the Newton iterations."""
    from mpi4py import MPI

    from fabricsurf.kinematics import fibre_directions

    sp = structured_rectangle(1.0, 1.0, n, n, comm or MPI.COMM_WORLD)
    msh = sp.mesh
    V = fem.VectorFunctionSpace(msh, ("CG", 2), dim=d)
    u = fem.Function(V)
    x = ufl.SpatialCoordinate(msh)
    ue = u_exact(x)
    nrm = ufl.FacetNormal(msh)
    L, M = fibre_directions(*angles)
    E = EnergyForm(model, u, L, M, sp.facet_tags,
                   normal_derivative={t: ufl.grad(ue) * nrm for t in EDGE_TAGS.values()},
                   penalty=penalty)
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    R = E.residual(v)
    load = ufl.replace(R, {u: ue})
    g = fem.Function(V)
    g.interpolate(fem.Expression(ue, V.element.interpolation_points()))
    bc = fem.dirichletbc(g, fem.locate_dofs_topological(V, 1, boundary_facets(msh)))
    solver = SNESSolver(R - load, E.jacobian(du, v), u, [bc], prefix=f"fabricsurf_mms{d}_")
    reason, its = solver.solve()
    if reason <= 0:
        raise RuntimeError(f"manufactured problem (n = {n}, d = {d}) did not converge: {reason}")
    return norms(u - ue, msh), its


def rates(errors: list[float], hs: list[float]) -> list[float]:
    """Observed orders log(e_i/e_{i+1}) / log(h_i/h_{i+1})."""
    return [float(np.log(errors[i] / errors[i + 1]) / np.log(hs[i] / hs[i + 1]))
            for i in range(len(errors) - 1)]


def richardson_summary(levels: list[int], values: list[float]) -> dict:
    """Observed rate and Richardson limit of a scalar computed on refinement levels.

    ``levels`` must grow by one constant ratio r (e.g. 2, 4, 8): with d_k = F_{k+1} − F_k,
    rate_k = log(|d_k| / |d_{k+1}|) / log r for each consecutive pair of differences (None
    where a difference is 0 or the two differences change sign: oscillation, no rate). The
    limit F_last + d_last / (r^rate − 1) and its error estimate |d_last| / (r^rate − 1) are
    given only when the last rate exists and is positive; otherwise None.
    """
    if len(levels) != len(values) or len(levels) < 2:
        raise ValueError(f"richardson_summary: need ≥ 2 levels with one value each, got "
                         f"{len(levels)} levels and {len(values)} values")
    ratios = {levels[i + 1] / levels[i] for i in range(len(levels) - 1)}
    if len(ratios) != 1 or min(ratios) <= 1:
        raise ValueError(f"richardson_summary: levels {levels} must grow by one constant ratio")
    r = ratios.pop()
    d = [values[i + 1] - values[i] for i in range(len(values) - 1)]
    rates = [float(np.log(abs(d[i] / d[i + 1])) / np.log(r)) if d[i] * d[i + 1] > 0 else None
             for i in range(len(d) - 1)]
    last = rates[-1] if rates else None
    err = abs(d[-1]) / (r**last - 1) if last is not None and last > 0 else None
    return {"differences": [abs(x) for x in d], "rates": rates, "finest_error_estimate": err,
            "extrapolated": None if err is None else values[-1] + d[-1] / (r**last - 1)}
