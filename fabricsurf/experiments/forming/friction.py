"""Coulomb friction of the sheet under the holder, on the punch and over the die's lip
(forming_tools.Tools), as incremental dissipation potentials of a load step, and the punch force
they add.

The same variational update as the holder's friction (Ortiz & Stainier 1999; forming_tools):
a step from the converged state r_n at stroke s_n to the stroke s adds to the energy

    Φ_tool(u; s) = ∫ μ_tool p_n (√(|Δr_t|² + ε²) − ε) dX,    ε = v_ε |s − s_n|,

with, for each tool,

* p_n = k_c ⟨−d(r_n)⟩ (the punch's: Tools.punch_pressure) the tool's contact pressure at r_n
  (per unit reference area): the normal pressure is explicit within the step, as the holder's
  is;
* Δr_t = P_n (Δr − Δs_tool e_z) the slip relative to the tool, projected on the tool's tangent
  plane at r_n (P_n = I − n nᵀ, n the tool's outward normal at r_n): the punch moves with the
  stroke, Δs_tool = s − s_n; the die stands still, Δs_tool = 0.

The die's friction acts over its lip only (where the die's nearest point is on the lip's torus
at r_n, ρ_n < R_o + r_d): on the die's flat face the flange is pressed by the holder, and its
friction on both faces is the holder's term (coefficient ``friction``, 2 μ p_h w).

Variation: the friction traction on the sheet is −τ, τ = μ p_n Δr_t / √(|Δr_t|² + ε²) —
Coulomb's law regularised for slips slower than v_ε per unit stroke. The energy dissipated in
the step is τ·Δr_t (traction times the relative slip).

**The punch force with punch friction.** The punch's potential depends on s through the
relative slip, ∂Φ_p/∂s|_u = −∫ τ_z dX (τ at fixed ε: ε is a regularisation, not a state). The
force on the punch is the vertical force the sheet exerts on it, the normal pressure's and the
friction's, F = ∫ (k_c ⟨−d_p⟩ n_z − τ_z) dX = ∂(Π + Φ)/∂s|_u. Along a path of equilibria
(∂Π/∂u = −τ in the continuous limit) dΠ/ds = ∂Π/∂s − τ·u′, so

    F − dΠ/ds = τ·u′ − τ_z = τ·(u′ − e_z) ≥ 0,

the rate of dissipation on the punch (the holder's and the lip's add τ·u′ the same way, their
potentials not depending on s): ∫ F ds = ΔΠ + D, D the sum of the steps' τ·Δr_t. The force
∂Π/∂s alone (without −τ_z) would miss the punch friction's work, and the balance would fail by
the punch's share of D. The discrete balance errs by the trapezoid rule's O(Δs²) on F and the
explicit pressure's lag, so it converges as the steps are refined (tests/test_tool_friction.py).

**Viscous stabilisation** (``stabilisation`` η, N/mm², off by default). A drag τ_v = η ṙ on
the sheet's motion per unit stroke, ṙ = dr/ds, as the incremental potential of the step
Φ_v = ∫ ½ (η/Δs) |r − r_n|² dX: its traction (η/Δs)(r − r_n) is η times the step's mean rate,
and the energy it dissipates in the step, (η/Δs)|r − r_n|², tends to ∫ η |ṙ|² ds as the steps
are refined, whatever their number. Where the quasi-static path is smooth it moves the answer
by O(η); where it snaps (a wrinkle forming, a fold through), Newton has no nearby equilibrium
to converge to, and the drag (whose stiffness η/Δs grows as the load stepper cuts Δs) carries
the sheet through at a dissipated energy the run reports (docs/tool_surfaces.md). Φ_v does not
depend on s at fixed u, so the punch force is unchanged in form and ∫ F ds = ΔΠ + D + D_v.
"""

from __future__ import annotations

import ufl


def _tangential(v, n):
    """v projected on the plane normal to the unit vector n."""
    return v - ufl.dot(v, n) * n


def _holder_slip(tools, r, r_n):
    """(|Δr_t|², the in-plane slip squared since r_n; 2 μ p_h w(σ_n), the limit traction)."""
    slip = ufl.as_vector([r[0] - r_n[0], r[1] - r_n[1]])
    return ufl.dot(slip, slip), 2.0 * tools.mu * tools.p_h * tools.holder_weight(r_n, last=True)


def holder_potential_density(tools, r, r_n):
    """The holder's Φ density 2 μ p_h w(σ_n) (√(|Δr_t|² + ε²) − ε) (N/mm per unit reference
    area; forming_tools), r_n the placement of the last converged state."""
    s2, limit = _holder_slip(tools, r, r_n)
    return limit * (ufl.sqrt(s2 + tools.eps**2) - tools.eps)


def holder_dissipation_density(tools, r, r_n):
    """The work of the holder's friction over the step's slip, 2 μ p_h w(σ_n) |Δr_t|² /
    √(|Δr_t|² + ε²) (N/mm per unit reference area): the energy dissipated in the step."""
    s2, limit = _holder_slip(tools, r, r_n)
    return limit * s2 / ufl.sqrt(s2 + tools.eps**2)


def punch_slip(tools, r, r_n):
    """(μ_p p_n, the limit traction; Δr_t, the slip relative to the punch in its tangent plane
    at r_n) of the step from (r_n, s_n) to (r, s)."""
    table = tools.tabulated_n  # a punch given as a surface: its table at r_n
    d_n, n = (tools if table is None else table).punch_normal(r_n, tools.stroke_n)
    rel = r - r_n - (tools.stroke - tools.stroke_n) * ufl.as_vector([0.0, 0.0, 1.0])
    limit = tools.mu_punch * tools.punch_pressure(d_n)
    return limit, _tangential(rel, n)


def lip_slip(tools, r, r_n):
    """(μ_d p_n, the limit traction over the die's lip; Δr_t, the slip in the lip's tangent
    plane at r_n); a die given as a surface from its table at r_n (:func:`table_lip_contact`)."""
    table = tools.die_table_n
    penetration, n = lip_contact(tools, r_n) if table is None else table_lip_contact(tools, r_n)
    return tools.mu_die * tools.k_c * penetration, _tangential(r - r_n, n)


def table_lip_contact(tools, r_n):
    """(penetration into a die given as a surface where the sheet is within one lip radius of
    the opening's outline, σ(r_n) < r_d, else 0; the die's normal there), from the die's table
    at r_n (tabulated_tools.py): the analytic die's lip where the die is that plate, the
    cavity's walls and floor of a matched die; beyond, the holder's friction acts."""
    table = tools.die_table_n
    on_lip = ufl.conditional(ufl.lt(tools.opening.sigma(r_n), tools.lip), 1.0, 0.0)
    return on_lip * ufl.max_value(-table.distance(r_n), 0.0), table.normal(r_n)


def lip_contact(tools, r):
    """(penetration into the die's lip, the tube about σ = r_d, where the die's nearest point is
    on it, else 0; the lip's outward normal): the analytic die's (tools.py)."""
    a = tools.opening.sigma(r) - tools.lip
    b = r[2] - (-tools.p_h / tools.k_c + tools.lip)
    dist = ufl.sqrt(a**2 + b**2)
    g = tools.opening.gradient(r)
    on_lip = ufl.conditional(ufl.lt(a, 0.0), 1.0, 0.0)
    n = ufl.as_vector([a * g[0], a * g[1], b]) / dist
    return on_lip * ufl.max_value(tools.lip - dist, 0.0), n


def _slips(tools, r, r_n):
    return (punch_slip(tools, r, r_n), lip_slip(tools, r, r_n))


def potential_density(tools, r, r_n):
    """Σ μ p_n (√(|Δr_t|² + ε²) − ε) over punch and lip (N/mm per unit reference area)."""
    return sum(
        limit * (ufl.sqrt(ufl.dot(t, t) + tools.eps**2) - tools.eps)
        for limit, t in _slips(tools, r, r_n)
    )


def dissipation_density(tools, r, r_n):
    """Σ τ·Δr_t = μ p_n |Δr_t|² / √(|Δr_t|² + ε²) over punch and lip: the step's dissipation
    (N/mm per unit reference area)."""
    return sum(
        limit * ufl.dot(t, t) / ufl.sqrt(ufl.dot(t, t) + tools.eps**2)
        for limit, t in _slips(tools, r, r_n)
    )


def punch_force_density(tools, r, r_n):
    """−τ_z of the punch's friction: its share of the punch force per unit reference area
    (N/mm², module docstring)."""
    limit, t = punch_slip(tools, r, r_n)
    return -limit * t[2] / ufl.sqrt(ufl.dot(t, t) + tools.eps**2)


def viscous_potential_density(tools, r, r_n):
    """½ (η/Δs) |r − r_n|² (N/mm per unit reference area): the viscous stabilisation's
    potential of the step, ``tools.damping`` = η/Δs (module docstring): half the step's
    dissipation."""
    return 0.5 * viscous_dissipation_density(tools, r, r_n)


def viscous_dissipation_density(tools, r, r_n):
    """(η/Δs) |r − r_n|², the drag's traction times the step's motion: the energy the
    stabilisation dissipates in the step (N/mm per unit reference area)."""
    step = r - r_n
    return tools.damping * ufl.dot(step, step)


def step_dissipation(tools, r, r_n) -> tuple:
    """(the friction's dissipation density of the step on every tool; the viscous
    stabilisation's, None while it is off)."""
    friction = holder_dissipation_density(tools, r, r_n) + dissipation_density(tools, r, r_n)
    return friction, viscous_dissipation_density(tools, r, r_n) if tools.stabilisation else None
