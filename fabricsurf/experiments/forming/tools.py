"""Rigid forming tools as analytic signed distances, their penalty contact, and the problem that
carries it (its solver: experiments/forming/contact_newton.py; used by the hemisphere plug-in,
experiments/hemisphere.py).

The placement r is in a frame whose origin is the punch axis at the blank's reference plane.
The punch is a hemisphere of radius R on a cylinder of the same radius, its pole at z = s (s
the stroke), pushing the blank up into the die (tools of any shape: given as surfaces and
tabulated, tabulated_tools.py). The die (above the blank, face at z = −p_h/k_c: the flat blank
pressed into it is in equilibrium at s = 0 with the die's penalty active, whose stiffness
would vanish at d = 0) and the blank holder (below it, face at z = −g, g the gap) are plates
with an opening (a circle of radius R_o, or a rectangle with rounded corners:
surfaces/opening.py, σ the signed distance from its outline in the plate's plane) and a
rounded lip of radius r_d. The holder presses the flange against the die with a pressure p_h,
the potential −∫ p_h w(σ) r_z dX, w rising smoothly (3t² − 2t³) from 0 one lip radius beyond
the end of the lip (σ = 2 r_d; the die's face is flat from σ = r_d) to 1 one lip radius
further: it fixes the blank's vertical position (in a gap alone it could float up).
Self-weight (optional) is the potential ∫ q r_z dX, q = ρ_A g per unit reference area.
Contact is the penalty ½ k_c ⟨−d⟩² per unit reference area for each tool's distance d; with
``contact_softening`` ε > 0 the punch's ⟨−d⟩ is the softplus ε ln(1 + e^(−d/ε)), whose pressure
begins just before touching (docs/tool_surfaces.md, "A box").

Friction (Coulomb, optional: under the holder μ, on the punch μ_p, over the die's lip μ_d) and
a viscous drag (``stabilisation``) enter as incremental dissipation potentials of a load step
from the last converged state r_n (Ortiz & Stainier 1999; experiments/forming/friction.py).
The punch force is the work conjugate of the stroke, F = ∂(Π + Φ)/∂s at fixed u =
∫ (p_c n_z − τ_z) dX (p_c the punch's contact pressure, n_z the vertical component of its
outward normal, τ_z that of its friction traction), so that ∫ F ds = ΔΠ + D along equilibrium
states, D the dissipation. A die or a holder given as a surface is tabulated (fixed_tools.py).
"""

from __future__ import annotations

import ufl
from dolfinx import fem

from fabricsurf.discretise.energy import placement
from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE
from fabricsurf.discretise.resources import release_vectors
from fabricsurf.discretise.solver import SNESSolver
from fabricsurf.experiments.cantilever import weight_per_area
from fabricsurf.experiments.forming import friction as forming_friction
from fabricsurf.experiments.forming import options as forming_options
from fabricsurf.experiments.forming.contact_newton import LINEAR_SOLVER, ContactSolver
from fabricsurf.experiments.forming.fixed_tools import tabulated_die, tabulated_holder
from fabricsurf.experiments.forming.surfaces.files import given_surface, punch_surface
from fabricsurf.experiments.forming.surfaces.holder import HolderPress, ramp
from fabricsurf.experiments.forming.surfaces.opening import Opening
from fabricsurf.experiments.forming.surfaces.opening_form import OpeningForm
from fabricsurf.experiments.forming.tabulated_tools import tabulated_punch
from fabricsurf.model.terms import Term


class Tools:
    """Punch, die and holder as UFL signed distances of the placement r (module docstring); the
    opening an Opening or a circle's radius. Sizes, stroke, penalty, pressure, friction and
    weight are fem.Constants (other sizes: the same compiled forms). ``friction``: the holder's
    coefficient (both faces); ``punch_friction``, ``die_friction``: the punch's and the lip's.
    :attr:`r_n` (the last converged placement) is set by the ContactProblem."""

    def __init__(
        self,
        msh,
        R: float,
        opening: float | Opening,
        gap: float,
        lip: float,
        k_c: float,
        pressure: float,
        friction: float = 0.0,
        slip_rate: float = 1e-2,
        weight: float = 0.0,
        punch_friction: float = 0.0,
        die_friction: float = 0.0,
        punch_surface=None,
        contact_softening: float = 0.0,
        stabilisation: float = 0.0,
        die_table=None,
        holder=None,
    ) -> None:
        self.R = float(R)
        self.outline = opening if isinstance(opening, Opening) else Opening.circle(opening)
        self.opening = OpeningForm(msh, self.outline)
        self.radius, self.gap, self.lip = (fem.Constant(msh, float(v)) for v in (R, gap, lip))
        self.softening, self.stabilisation = float(contact_softening), float(stabilisation)
        self.k_c, self.p_h, self.mu, self.weight, self.eps_c = (
            fem.Constant(msh, float(v))
            for v in (k_c, pressure, friction, weight, self.softening or 1.0)
        )
        self.slip_rate = float(slip_rate)
        self.eps, self.stroke, self.stroke_n, self.damping = (
            fem.Constant(msh, v) for v in (1.0, 0.0, 0.0, 0.0)
        )  # damping: η/Δs of the step, set by the solver
        self.mu_punch = fem.Constant(msh, float(punch_friction))
        self.mu_die = fem.Constant(msh, float(die_friction))
        self.r_n = None
        self.tabulated = tabulated_punch(msh, punch_surface, self.softening)
        self.die_table = die_table
        self.holder_table, footprint = (None, None) if holder is None else holder
        self.press = None if footprint is None else HolderPress(msh, footprint, self.lip)
        self.tables = [t for t in (self.tabulated, die_table, self.holder_table, self.press) if t]
        self.tabulated_n, self.die_table_n, self.press_n = (  # at r_n, for friction.py
            None if t is None else t.twin() for t in (self.tabulated, die_table, self.press)
        )
        self.last_tables = [t for t in (self.tabulated_n, self.die_table_n, self.press_n) if t]

    @classmethod
    def from_options(cls, msh, o: dict) -> Tools:
        """The tools of the hemisphere plug-in's checked options (forming_options.parse)."""
        return cls(
            msh,
            o["punch_radius"],
            forming_options.opening(o),
            o["holder_gap"],
            o["die_lip"],
            o["contact_stiffness"],
            o["holder_pressure"],
            o.get("friction", 0.0),
            o.get("friction_slip_rate", 1e-2),
            weight_per_area(o.get("areal_density_g_m2", 0.0)),
            o.get("punch_friction", 0.0),
            o.get("die_friction", 0.0),
            punch_surface(o),
            o.get("contact_softening", 0.0),
            o.get("stabilisation", 0.0),
            None if (die := given_surface(o, "die")) is None else tabulated_die(msh, die, o),
            tabulated_holder(msh, o),
        )

    def tool_friction(self) -> bool:
        """Whether the punch or the die's lip has friction (its forms are then assembled)."""
        return float(self.mu_punch.value) != 0.0 or float(self.mu_die.value) != 0.0

    def _rho(self, r):
        """Distance from the punch axis, regularised on it (its derivative is then finite)."""
        return ufl.sqrt(r[0] ** 2 + r[1] ** 2 + 1e-12 * self.radius**2)

    def punch(self, r, stroke=None):
        """(signed distance to the punch, the vertical component of its outward normal), the
        pole at ``stroke`` (default: the current stroke); a punch given as a surface from its
        table (tabulated_tools.py)."""
        if self.tabulated is not None:
            return self.tabulated.punch(r, self.stroke if stroke is None else stroke)
        dz, rho = r[2] - ((self.stroke if stroke is None else stroke) - self.radius), self._rho(r)
        dist, cap = ufl.sqrt(rho**2 + dz**2), ufl.gt(dz, 0.0)
        return (
            ufl.conditional(cap, dist - self.radius, rho - self.radius),
            ufl.conditional(cap, dz / dist, 0.0),
        )

    def punch_normal(self, r, stroke):
        """(signed distance to the punch with its pole at ``stroke``, its outward normal)."""
        if self.tabulated is not None:
            return self.tabulated.punch_normal(r, stroke)
        d, _ = self.punch(r, stroke)
        dz, rho = r[2] - (stroke - self.radius), self._rho(r)
        cap = ufl.as_vector([r[0], r[1], dz]) / ufl.sqrt(rho**2 + dz**2)
        side = ufl.as_vector([r[0] / rho, r[1] / rho, 0.0])
        return d, ufl.conditional(ufl.gt(dz, 0.0), cap, side)

    def _plate(self, r, side: float):
        """Signed distance to the die (side = 1, above) or the holder (side = −1, below): the
        lip's tube of radius r_d about σ = r_d and, beyond it, the flat face; a die or a holder
        given as a surface from its table (tabulated_tools.py)."""
        table = self.die_table if side > 0 else self.holder_table
        if table is not None:
            return table.distance(r)
        a = self.opening.sigma(r) - self.lip
        face = -self.p_h / self.k_c if side > 0 else -self.gap
        torus = ufl.sqrt(a**2 + (r[2] - face - side * self.lip) ** 2) - self.lip
        return ufl.conditional(ufl.gt(a, 0.0), side * (face - r[2]), torus)

    def penetrations(self, r) -> dict:
        """⟨−d⟩ of each tool (mm)."""
        return {
            "punch": ufl.max_value(-self.punch(r)[0], 0.0),
            "die": ufl.max_value(-self._plate(r, 1.0), 0.0),
            "holder": ufl.max_value(-self._plate(r, -1.0), 0.0),
        }

    def holder_weight(self, r, last: bool = False):
        """w(σ) of the holder pressure (module docstring); a holder given as a surface's from its
        table at r, or at r_n if ``last`` (surfaces/holder.py)."""
        if self.press is not None:
            return (self.press_n if last else self.press).weight(r)
        return ramp(self.opening.sigma(r) / self.lip - 2.0)

    def energy_density(self, r):
        """½ k_c Σ ⟨−d⟩² − p_h w r_z + q r_z (N/mm per unit reference area; q the self-weight
        per unit reference area, N/mm², gravity along −z), the punch's ⟨−d⟩ its depth p(d)."""
        pen = {**self.penetrations(r), "punch": self.punch_depth(self.punch(r)[0])}
        return (
            0.5 * self.k_c * sum(p**2 for p in pen.values())
            - self.p_h * self.holder_weight(r) * r[2]
            + self.weight * r[2]
        )

    def punch_depth(self, d):
        """The punch's depth p(d) in the penalty ½ k_c p²: ⟨−d⟩, or with a softening ε the
        softplus ε ln(1 + e^(−d/ε)), C^∞, a little above ⟨−d⟩ (by ε ln 2 at d = 0)."""
        if self.softening == 0.0:
            return ufl.max_value(-d, 0.0)
        t = -d / self.eps_c
        return self.eps_c * (ufl.max_value(t, 0.0) + ufl.ln(1.0 + ufl.exp(-abs(t))))

    def punch_pressure(self, d):
        """k_c p ∂p/∂(−d): the punch's contact pressure (N/mm² of reference area)."""
        slope = 1.0 if self.softening == 0.0 else 1.0 / (1.0 + ufl.exp(d / self.eps_c))
        return self.k_c * self.punch_depth(d) * slope

    def force_density(self, r):
        """p_c n_z − τ_z, p_c the punch's contact pressure: the punch force per unit reference
        area (N/mm²), the punch friction's τ_z once :attr:`r_n` is set (forming_friction.py)."""
        normal = self.punch_pressure(self.punch(r)[0]) * self.punch(r)[1]
        if self.r_n is None:
            return normal
        return normal + forming_friction.punch_force_density(self, r, self.r_n)

    def pressure(self, r):
        """Contact pressure of all tools (N/mm² of reference area)."""
        pen = self.penetrations(r)
        return self.punch_pressure(self.punch(r)[0]) + self.k_c * (pen["die"] + pen["holder"])


class ContactProblem(FabricProblem):
    """A FabricProblem whose energy also holds the tools' contact penalty; its residual and
    Jacobian are the variations of that one energy (``ufl.derivative``). Its linear solver is
    :data:`LINEAR_SOLVER` unless ``snes_options`` say otherwise."""

    def __init__(
        self, specimen, model: list[Term], tools: Tools, fallback: dict | None = None, **kw
    ) -> None:
        kw["snes_options"] = {**LINEAR_SOLVER, **(kw.get("snes_options") or {})}
        super().__init__(specimen, model, **kw)
        self.tools, self.fallback = tools, fallback
        self.u_n = fem.Function(self.V, name="u_n")
        self.dx = ufl.Measure(
            "dx", domain=self.msh, metadata={"quadrature_degree": CELL_QUADRATURE_DEGREE}
        )
        tools.r_n = placement(self.u_n)
        for table in tools.tables:
            table.attach(placement(self.u), tools.stroke)
        for table in tools.last_tables:
            table.attach(tools.r_n, tools.stroke_n)

    def _release(self) -> None:
        super()._release()
        release_vectors(self.u_n)

    def contact_energy(self):
        return self.tools.energy_density(placement(self.u)) * self.dx

    def friction_energy(self):
        """Φ of the holder's friction and the viscous drag of the step from u_n (friction.py)."""
        r, r_n = placement(self.u), placement(self.u_n)
        phi = forming_friction.holder_potential_density(self.tools, r, r_n)
        if self.tools.stabilisation:
            phi = phi + forming_friction.viscous_potential_density(self.tools, r, r_n)
        return phi * self.dx

    def mirror(self, edge: str, axis: int) -> None:
        """Mirror symmetry about a straight edge normal to the reference axis ``axis``: the
        normal component of u vanishes there, and the normal derivatives of the others do
        (weakly, by the Nitsche terms of ∂_n u = g with g holding ∂_n u_axis itself)."""
        self.fix(edge, [0.0 if i == axis else None for i in range(3)])
        n = ufl.FacetNormal(self.msh)
        dn = ufl.grad(self.u) * n
        self.clamp_gradient(edge, ufl.as_vector([dn[i] if i == axis else 0.0 for i in range(3)]))

    def extra_energy(self):
        return self.contact_energy() + self.friction_energy()

    def tool_friction(self) -> tuple:
        """(residual, Jacobian) of the punch's and the lip's friction potentials
        (forming_friction.py): variations of one energy, like the main forms."""
        r, r_n = placement(self.u), placement(self.u_n)
        phi = forming_friction.potential_density(self.tools, r, r_n) * self.dx
        dP = ufl.derivative(phi, self.u, ufl.TestFunction(self.V))
        return dP, ufl.derivative(dP, self.u, ufl.TrialFunction(self.V))

    def _new_solver(self, F, J, nodal_forces) -> SNESSolver:
        r, r_n = placement(self.u), placement(self.u_n)
        friction, viscous = forming_friction.step_dissipation(self.tools, r, r_n)
        return ContactSolver(
            F,
            J,
            self.u,
            self.bcs,
            self.prefix,
            self.snes_options,
            nodal_forces,
            self.energy.multipliers,
            tools=self.tools,
            fallback=self.fallback,
            u_n=self.u_n,
            dissipation=friction * self.dx,
            damping=None if viscous is None else viscous * self.dx,
            tool_friction=self.tool_friction(),
            history=ufl.derivative(self.friction_energy(), self.u, ufl.TestFunction(self.V)),
        )
