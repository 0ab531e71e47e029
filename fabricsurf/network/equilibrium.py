"""Newton solver with kinematic constraints and load stepping for a SpringNetwork [B (23)-(24)].

Constraints are perfect bilateral ones that prescribe node displacements [B Table 1], so
they are eliminated instead of carried with Lagrange multipliers: the free dofs solve
``f_free(q) = 0`` by Newton; the constraint forces W(q) lambda of [B (23)] are the
internal forces ``-f`` on the constrained dofs, and the *reaction* on a node set is the
sum of the internal forces ``f = dE/dq`` on it (the force the grip applies to the sheet).

Load stepping: the prescribed displacements are ``t * u_final`` with load factor t in
[0, 1]; a step that does not converge is cut in half until ``min_step``, then
:class:`ConvergenceError` is raised.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from fabricsurf.network.engine import SpringNetwork
from fabricsurf.network.linsolve import FreeDofSolver


class ConvergenceError(RuntimeError):
    """Newton failed and the load step cannot be cut further."""


@dataclass
class Dirichlet:
    """Prescribed displacement ``t * u_final`` of a node set (both components).

    ``u_final`` is (2,) (same for all nodes) or (len(nodes), 2). A clamp is ``u_final=0``.
    """

    nodes: np.ndarray
    u_final: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def displacement(self, t: float) -> np.ndarray:
        return t * np.broadcast_to(np.asarray(self.u_final, float), (len(self.nodes), 2))


@dataclass
class NewtonInfo:
    converged: bool
    iterations: int
    residual: float
    seconds: float


@dataclass
class StepResult:
    """Converged state at load factor ``t``; ``reactions[name]`` is a (2,) force in N."""

    t: float
    x: np.ndarray
    reactions: dict
    iterations: int
    seconds: float


def _constrained(bcs: list[Dirichlet], n: int, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Constrained dof mask (2n,) and the prescribed positions offset (n, 2)."""
    fixed = np.zeros((n, 2), bool)
    u = np.zeros((n, 2))
    for bc in bcs:
        nodes = np.asarray(bc.nodes, np.int64)
        fixed[nodes] = True
        u[nodes] = bc.displacement(t)
    return fixed.ravel(), u


def newton(
    net: SpringNetwork,
    x: np.ndarray,
    fixed: np.ndarray,
    rtol: float = 1e-10,
    atol: float = 1e-9,
    maxit: int = 30,
    max_halvings: int = 10,
    linear: FreeDofSolver | None = None,
) -> tuple[np.ndarray, NewtonInfo]:
    """Minimise E over the free dofs from ``x`` (the constrained dofs of ``x`` are kept).

    Newton-Raphson on ``f_free = 0`` [B (24)] with a backtracking line search on the
    residual norm. Converged when ``|f_free|_2 <= max(atol, rtol * |f_free(x0)|_2)`` (N).
    Linear solves: :class:`~fabricsurf.network.linsolve.FreeDofSolver` (``splu`` with a
    nested-dissection ordering; pass one to reuse its ordering and lagged factors).
    """
    t0 = time.perf_counter()
    q = np.asarray(x, float).ravel().copy()
    free = ~fixed
    r = net.gradient(q.reshape(-1, 2)).ravel()[free]
    rn = r0 = float(np.linalg.norm(r))
    tol = max(atol, rtol * r0)
    for it in range(1, maxit + 1):
        if rn <= tol:
            return q.reshape(-1, 2), NewtonInfo(True, it - 1, rn, time.perf_counter() - t0)
        H = net.hessian(q.reshape(-1, 2))
        if linear is None:
            linear = FreeDofSolver(net.X, H, free)
        try:
            dq = linear.solve(H, -r)
        except RuntimeError:  # singular block
            break
        if not np.all(np.isfinite(dq)):
            break
        alpha = 1.0
        for _ in range(max_halvings + 1):
            qn = q.copy()
            qn[free] += alpha * dq
            rnew = net.gradient(qn.reshape(-1, 2)).ravel()[free]
            rnn = float(np.linalg.norm(rnew))
            if np.isfinite(rnn) and (rnn < rn or rnn <= tol):
                break
            alpha *= 0.5
        else:
            break
        q, r, rn = qn, rnew, rnn
    ok = rn <= tol
    return q.reshape(-1, 2), NewtonInfo(ok, it, rn, time.perf_counter() - t0)


def reaction(net: SpringNetwork, x: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Reaction on a node set: sum of the internal forces dE/dq on its nodes [B (22)], N."""
    return net.gradient(x)[np.asarray(nodes, np.int64)].sum(axis=0)


def tangent_predictor(
    net: SpringNetwork,
    x: np.ndarray,
    fixed: np.ndarray,
    x_fixed_new: np.ndarray,
    linear: FreeDofSolver,
) -> np.ndarray:
    """Linearised response to moving the constrained dofs: H_ff Δq_f = −H_fc Δq_c (at an
    equilibrium x), the predictor of a load step that starts from rest; returns the guess."""
    q = np.asarray(x, float).ravel()
    dq = np.zeros_like(q)
    dq[fixed] = np.asarray(x_fixed_new, float).ravel()[fixed] - q[fixed]
    H = net.hessian(x)
    dq[~fixed] = linear.solve(H, -(H @ dq)[~fixed])
    return (q + dq).reshape(-1, 2)


def solve_steps(
    net: SpringNetwork,
    bcs: list[Dirichlet],
    n_steps: int = 10,
    x0: np.ndarray | None = None,
    reaction_sets: dict | None = None,
    min_step: float = 1e-4,
    newton_kw: dict | None = None,
    callback=None,
    stops=(),
) -> list[StepResult]:
    """Load stepping t: 0 -> 1 in ``n_steps`` equal steps with step cutting.

    ``stops``: load factors in (0, 1) that a step must end on exactly (the states a caller
    samples on the way, for instance every displacement of a test's path in one continuation
    rather than each solved from rest: the energy has no history, so the state at a load
    factor does not depend on the path to it).

    Each step starts from the last converged state, with the prescribed nodes moved to
    their new positions and the free nodes predicted by the tangent (first step) or
    extrapolated linearly from the previous step.
    A failed step is halved; below ``min_step`` (as a fraction of the total load) a
    :class:`ConvergenceError` is raised naming the load factor reached. Results are
    recorded at every converged step (cut steps included).
    """
    newton_kw = dict(newton_kw or {})
    reaction_sets = reaction_sets or {}
    x = net.X.copy() if x0 is None else np.asarray(x0, float).copy()
    if "linear" not in newton_kw:
        fixed, _ = _constrained(bcs, net.n_nodes, 0.0)
        newton_kw["linear"] = FreeDofSolver(net.X, net.hessian(x), ~fixed)
    t, dt, dx_prev, dx_prev_dt = 0.0, 1.0 / n_steps, None, 1.0
    ends = np.unique(np.r_[[s for s in stops if 0.0 < s < 1.0], 1.0])
    out: list[StepResult] = []
    while t < 1.0 - 1e-12:
        dt = min(dt, ends[np.searchsorted(ends, t + 1e-12)] - t)
        fixed, u = _constrained(bcs, net.n_nodes, t + dt)
        if dx_prev is None:
            guess = tangent_predictor(net, x, fixed, net.X + u, newton_kw["linear"])
        else:
            guess = x + dx_prev * (dt / dx_prev_dt)
        fmask = fixed.reshape(-1, 2)
        guess[fmask] = (net.X + u)[fmask]
        xn, info = newton(net, guess, fixed, **newton_kw)
        if not info.converged:
            dt *= 0.5
            if dt < min_step:
                raise ConvergenceError(
                    f"Newton did not converge at load factor {t:.6g} + {2 * dt:.3g}; "
                    f"step cut below min_step={min_step:g} (last residual {info.residual:.3e} N)"
                )
            continue
        dx_prev, dx_prev_dt = xn - x, dt
        x, t = xn, t + dt
        reac = {k: reaction(net, x, v) for k, v in reaction_sets.items()}
        out.append(StepResult(t, x.copy(), reac, info.iterations, info.seconds))
        if callback is not None:
            callback(out[-1])
        dt = min(2 * dt, 1.0 / n_steps)
    return out
