"""Rigid forming tools as analytic signed distances, their penalty contact, and the problem and
solver that carry it (used by the hemisphere plug-in, experiments/hemisphere.py).

The placement r is in a frame whose origin is the punch axis at the blank's reference plane.
The punch is a hemisphere of radius R on a cylinder of the same radius, its pole at z = s (s
the stroke), pushing the blank up into the die. The die (above the blank, face at z = −p_h/k_c,
so that the flat blank pressed into it is in equilibrium at s = 0 and the die's penalty is
active there: at d = 0 its stiffness would vanish and leave the vertical motion free) and
the blank holder (below it, face at z = −g, g the gap) are plates with a circular opening of
radius R_o and a rounded lip of radius r_d. The holder also presses the flange against the die
with a pressure p_h, the potential −∫ p_h w(ρ) r_z dX, w rising smoothly (3t² − 2t³) from 0
one lip radius beyond the end of the lip (ρ = R_o + 2 r_d, ρ the current distance from the
axis; the die's face becomes flat at R_o + r_d) to 1 one lip radius further: it fixes the blank's
vertical position from the first step (a blank in a gap alone could float up with the punch).
Self-weight, optional, is the potential ∫ q r_z dX (q = ρ_A g per unit reference area).
Contact is the penalty energy
½ k_c ⟨−d⟩² per unit reference area for each tool's signed distance d.

Friction under the holder (Coulomb, coefficient μ, optional): without it nothing resists the
flange's draw-in, the fibres carry no tension, and the sheet spans the punch as a tent held by
its small shear and bending stiffnesses instead of wrapping it (a membrane presses on a curved
tool with p = T κ; with T = 0 only bending presses, at a few points). The holder's pressure p_h
acts on both faces of the flange (holder below, die above), so the friction traction opposes
the in-plane slip with magnitude 2 μ p_h w. It enters as the incremental dissipation potential
of a load step (the variational update of Ortiz & Stainier 1999):
Φ = ∫ 2 μ p_h w(ρ_n) (√(|Δr_t|² + ε²) − ε) dX, Δr_t the in-plane slip since the last converged
state r_n, ε = v_ε Δs the regularising slip of a step of stroke Δs (v_ε a slip rate, mm of slip
per mm of stroke, so that the regularisation is of the slip rate and does not grow as the steps
shrink); w is taken at r_n, so that the normal pressure is explicit within a step. A converged
step then satisfies Coulomb's law (|t| ≤ 2 μ p_h w, sliding against the slip) up to slips
slower than v_ε. Friction on the punch and over the die's lip is
not modelled. The punch force is the work conjugate of the stroke,
F = ∂Π/∂s at fixed u = ∫ k_c ⟨−d_p⟩ n_z dX (n_z: the vertical component of the punch's outward
normal), so that ∫ F ds = ΔΠ along equilibrium states (the envelope theorem).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.energy import CELL_QUADRATURE_DEGREE, placement
from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.discretise.resources import release_vectors
from fabricsurf.discretise.solver import SOLVER_KEYS, SNESSolver
from fabricsurf.model.terms import Term


class Tools:
    """Punch, die and holder as UFL signed distances of the placement r (module docstring).
    Sizes, stroke, penalty, pressure, friction and weight are fem.Constants: tools of other
    sizes use the same compiled forms."""

    def __init__(self, msh, R: float, opening: float, gap: float, lip: float,
                 k_c: float, pressure: float, friction: float = 0.0,
                 slip_rate: float = 1e-2, weight: float = 0.0) -> None:
        self.R = float(R)
        self.radius, self.opening, self.gap, self.lip = (fem.Constant(msh, float(v))
                                                         for v in (R, opening, gap, lip))
        self.stroke = fem.Constant(msh, 0.0)
        self.k_c = fem.Constant(msh, float(k_c))
        self.p_h = fem.Constant(msh, float(pressure))
        self.mu = fem.Constant(msh, float(friction))
        self.weight = fem.Constant(msh, float(weight))
        self.slip_rate = float(slip_rate)
        self.eps = fem.Constant(msh, 1.0)

    def _rho(self, r):
        """Distance from the punch axis, regularised on it (its derivative is then finite)."""
        return ufl.sqrt(r[0] ** 2 + r[1] ** 2 + 1e-12 * self.radius**2)

    def punch(self, r):
        """(signed distance to the punch, the vertical component of its outward normal)."""
        dz = r[2] - (self.stroke - self.radius)
        rho = self._rho(r)
        dist = ufl.sqrt(rho**2 + dz**2)
        cap = ufl.gt(dz, 0.0)
        return (ufl.conditional(cap, dist - self.radius, rho - self.radius),
                ufl.conditional(cap, dz / dist, 0.0))

    def _plate(self, r, side: float):
        """Signed distance to the die (side = 1, above) or the holder (side = −1, below): a lip
        torus of tube radius r_d at the opening and, beyond it, the flat face."""
        rho, rho0 = self._rho(r), self.opening + self.lip
        face = -self.p_h / self.k_c if side > 0 else -self.gap
        torus = ufl.sqrt((rho - rho0) ** 2 + (r[2] - face - side * self.lip) ** 2) - self.lip
        return ufl.conditional(ufl.gt(rho, rho0), side * (face - r[2]), torus)

    def penetrations(self, r) -> dict:
        """⟨−d⟩ of each tool (mm)."""
        return {"punch": ufl.max_value(-self.punch(r)[0], 0.0),
                "die": ufl.max_value(-self._plate(r, 1.0), 0.0),
                "holder": ufl.max_value(-self._plate(r, -1.0), 0.0)}

    def holder_weight(self, r):
        """w(ρ) of the holder pressure (module docstring)."""
        t = ufl.min_value(ufl.max_value((self._rho(r) - self.opening) / self.lip - 2.0, 0.0), 1.0)
        return t**2 * (3.0 - 2.0 * t)

    def energy_density(self, r):
        """½ k_c Σ ⟨−d⟩² − p_h w r_z + q r_z (N/mm per unit reference area; q the self-weight
        per unit reference area, N/mm², gravity along −z)."""
        return (0.5 * self.k_c * sum(p**2 for p in self.penetrations(r).values())
                - self.p_h * self.holder_weight(r) * r[2] + self.weight * r[2])

    def _slip_and_limit(self, r, r_n):
        """(|Δr_t|², the in-plane slip squared since r_n; 2 μ p_h w(ρ_n), the limit traction)."""
        slip = ufl.as_vector([r[0] - r_n[0], r[1] - r_n[1]])
        return ufl.dot(slip, slip), 2.0 * self.mu * self.p_h * self.holder_weight(r_n)

    def friction_density(self, r, r_n):
        """Φ's density 2 μ p_h w(ρ_n) (√(|Δr_t|² + ε²) − ε) (N/mm per unit reference area;
        module docstring), r_n the placement of the last converged state."""
        s2, limit = self._slip_and_limit(r, r_n)
        return limit * (ufl.sqrt(s2 + self.eps**2) - self.eps)

    def dissipation_density(self, r, r_n):
        """The work of the friction traction over the step's slip, 2 μ p_h w(ρ_n) |Δr_t|² /
        √(|Δr_t|² + ε²) (N/mm per unit reference area): the energy dissipated in the step."""
        s2, limit = self._slip_and_limit(r, r_n)
        return limit * s2 / ufl.sqrt(s2 + self.eps**2)

    def force_density(self, r):
        """k_c ⟨−d_p⟩ n_z: the punch force per unit reference area (N/mm²)."""
        return self.k_c * self.penetrations(r)["punch"] * self.punch(r)[1]

    def pressure(self, r):
        """Contact pressure k_c Σ ⟨−d⟩ (N/mm² of reference area)."""
        return self.k_c * sum(self.penetrations(r).values())


class ContactSolver(SNESSolver):
    """SNESSolver that follows the stroke: a secant predictor, and full Newton steps with the
    ``l2`` line search as a fallback.

    A solve starts from the last converged state (the load stepper restores it after a failed
    attempt): that state is copied to ``u_n``, the r_n of the friction potential, first, and
    the regularising slip set from the stroke increment since it (``s_n``). The start is then
    extrapolated along the path through the last two converged states (u_n + (s − s_n)/(s_n −
    s_prev)·(u_n − u_prev)): a stroke increment moves the whole sheet (the flange draws in, the
    net shears), and Newton started from the previous state spends most of its iterations
    finding that motion. Newton takes full steps first; if that attempt fails, it is repeated
    from the same predicted state with ``fallback`` options (the ``l2`` line search, which
    damps the overshoot at the kinks of the contact residual) before the load stepper cuts the
    increment (docs/forming.md, measured). :attr:`fallbacks` counts those repeats. A converged
    solve adds the friction work of its step (``dissipation``, one quarter of the blank) to
    :attr:`dissipated`."""

    def __init__(self, *args, tools: Tools, u_n: fem.Function, dissipation,
                 fallback: dict | None = None, **kw) -> None:
        super().__init__(*args, **kw)
        self.tools, self.u_n = tools, u_n
        self._dissipation = fem.form(dissipation)
        options = args[5] if len(args) > 5 else kw.get("options")
        self._options = {k: v for k, v in (options or {}).items() if k not in SOLVER_KEYS}
        self._fallback = fallback
        self.reset()

    def reset(self) -> None:
        """Back to the flat blank at s = 0: no displacement, dissipation or path history."""
        self.u.x.array[:] = 0.0
        self.dissipated, self.s_n = 0.0, 0.0
        self.u_prev: np.ndarray | None = None
        self.s_prev = 0.0
        self.fallbacks = 0

    def _predict(self, s: float) -> None:
        """Extrapolate u along the path through (s_prev, u_prev) and (s_n, u_n) to s."""
        if self.u_prev is not None and self.s_n != self.s_prev:
            f = (s - self.s_n) / (self.s_n - self.s_prev)
            self.u.x.array[:] += f * (self.u_n.x.array - self.u_prev)

    def solve(self) -> tuple[int, int]:
        self.u_n.x.array[:] = self.u.x.array
        s = float(self.tools.stroke.value)
        self.tools.eps.value = self.tools.slip_rate * max(abs(s - self.s_n), 1e-6 * self.tools.R)
        self._predict(s)
        predicted = self.u.x.array.copy()
        reason, its = super().solve()
        if reason <= 0 and self._fallback:
            self.fallbacks += 1
            self.u.x.array[:] = predicted
            self.set_options({**self._options, **self._fallback})
            try:
                reason, more = super().solve()
            finally:
                self.set_options(self._options)
            its += more
        if reason > 0:
            self.u_prev, self.s_prev, self.s_n = self.u_n.x.array.copy(), self.s_n, s
            self.dissipated += self.comm.allreduce(fem.assemble_scalar(self._dissipation),
                                                   op=MPI.SUM)
        return reason, its


class ContactProblem(FabricProblem):
    """A FabricProblem whose energy also holds the tools' contact penalty; its residual and
    Jacobian are the variations of that one energy (``ufl.derivative``)."""

    def __init__(self, specimen, model: list[Term], tools: Tools,
                 fallback: dict | None = None, **kw) -> None:
        super().__init__(specimen, model, **kw)
        self.tools, self.fallback = tools, fallback
        self.u_n = fem.Function(self.V, name="u_n")
        self.dx = ufl.Measure("dx", domain=self.msh,
                              metadata={"quadrature_degree": CELL_QUADRATURE_DEGREE})

    def _release(self) -> None:
        super()._release()
        release_vectors(self.u_n)

    def contact_energy(self):
        return self.tools.energy_density(placement(self.u)) * self.dx

    def friction_energy(self):
        """Φ, the friction potential of the step from u_n (Tools.friction_density)."""
        return self.tools.friction_density(placement(self.u), placement(self.u_n)) * self.dx

    def mirror(self, edge: str, axis: int) -> None:
        """Mirror symmetry about a straight edge normal to the reference axis ``axis``: the
        normal component of u vanishes there, and the normal derivatives of the others do
        (weakly, by the Nitsche terms of ∂_n u = g with g holding ∂_n u_axis itself)."""
        self.fix(edge, [0.0 if i == axis else None for i in range(3)])
        n = ufl.FacetNormal(self.msh)
        dn = ufl.grad(self.u) * n
        self.clamp_gradient(edge, ufl.as_vector([dn[i] if i == axis else 0.0
                                                 for i in range(3)]))

    def extra_energy(self):
        return self.contact_energy() + self.friction_energy()

    def _new_solver(self, F, J, nodal_forces) -> SNESSolver:
        return ContactSolver(F, J, self.u, self.bcs, self.prefix, self.snes_options,
                             nodal_forces, self.energy.multipliers, tools=self.tools,
                             fallback=self.fallback,
                             u_n=self.u_n, dissipation=self.tools.dissipation_density(
                                 placement(self.u), placement(self.u_n)) * self.dx)
