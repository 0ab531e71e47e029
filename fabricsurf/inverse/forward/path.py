"""Sensitivities along a path history: the forming problem's friction (experiments/forming)
makes each load step's residual depend on the state r_n the step started from, R(u; p, u_n),
so the converged state of step i depends on the moduli through u_n as well:

    K_i du_i/dp = −∂R_i/∂p − (∂R_i/∂u_n) du_{i−1}/dp,

a recursion over the converged steps of the path from the flat blank (du_0/dp = 0): the
recorded steps, not the solves of cut increments between them, which are continuation only
(contact_newton.py); and a reaction functional F(u, u_n) (the punch force
with the punch's friction traction) has dF/dp = ∂F/∂p + (∂F/∂u) du_i/dp + (∂F/∂u_n) du_{i−1}/dp.
Each solve costs one back-substitution per modulus with the factorisation Newton left, as the
per-step sensitivities do. Per-step sensitivities, which hold u_n fixed, drift from the true
ones as the strokes add up, by far more on a tool that the sheet slides over than on a
hemisphere (docs/forming.md "Path history" has the measurements).

The tools given as surfaces (tabulated_tools.py) enter through tables of closest points and
normals at r_n, fixed over a step; an analytic shape's tables also hold its curvature, and
∂/∂u_n then turns the normal with it, as their Jacobian does (a triangle mesh's faces are flat).
"""

from __future__ import annotations

from fabricsurf.inverse.forward import tangent


class PathSensitivities:
    """du/dp for the moduli ``which`` (indices into ``fm.params``) carried over every step of
    the path that forward model ``fm``'s solver converges, whose ``on_converged`` it takes for
    the block (a context manager); :attr:`current` holds the last step's (du/dp, dF/dp), the
    reaction R·w with ``weight()`` (None: the test's reaction functional, if any)."""

    def __init__(self, fm, which: list[int], weight) -> None:
        self.fm, self.which, self.weight = fm, which, weight
        self.solver = fm.test.solver
        self.current: list | None = None

    def __enter__(self) -> PathSensitivities:
        self.current = None
        self.solver.on_converged = self._converged
        return self

    def __exit__(self, *exc) -> None:
        self.solver.on_converged = None

    def _converged(self) -> None:
        start = None if self.current is None else [du for du, _ in self.current]
        self.current = tangent.sensitivities(self.fm, self.which, self.weight(), start)


def along_path(fm, which: list[int]) -> bool:
    """Whether the forward model's sensitivities must follow the path (module docstring)."""
    depends = getattr(fm.test.solver, "path_dependent", None)
    return bool(which) and depends is not None and depends()
