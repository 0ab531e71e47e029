"""The discrete total energy Π_h of a second-gradient fabric surface (docs/theory.md).

Π_h(u) = Σ_K ∫_K W(F, H) dx                                   (broken Hessians H = ∇∇r on cells)
       + Σ_e ∫_e ( −[[∂_n r]]·{M_nn} + α S/(2 h_e) |[[∂_n r]]|² ) dS     (C0 interior penalty)
       + Σ_Γ ∫_Γ ( −(∂_n r − g)·M_nn + α S/(2 h) |∂_n r − g|² ) ds        (Nitsche: ∂_n r = g on Γ)
       − ∫ t·u ds                                                      (dead edge loads)

M = ∂W/∂H is the double-force tensor of the second-gradient terms (Steigmann & dell'Isola 2015 eq.
82) and M_nn = M[:, a, b] n_a n_b the edge double force (eq. 94). At the exact solution the jumps
vanish, so the method is consistent; it is the symmetric C0-IP of dolfinx's demo_biharmonic written
as an energy, whose variation gives residual and Jacobian through ``ufl.derivative``.

The penalty α/h scales with S, the sum of the second-gradient moduli, so the penalty keeps its
ratio to the physical stiffness when moduli change (no recompilation: S is built from the moduli's
fem.Constants). S may vary from cell to cell (a term whose moduli depend on the state, e.g. the
bi-pantographic coefficients, evaluates them on a DG0 field); on an interior facet the larger of
the two cells' values is taken, so the penalty dominates on both sides. The constants belong to the
form: an EnergyForm asks each term for its own on its mesh (``Term.constants``) and builds every
expression from them, so forms on several meshes, of one model or several, never share or swap
constants. An EnergyForm (and a FabricProblem) binds the very term objects it is given, so
``Term.set`` on them reaches it; the tests and forward models above it hand it their own copies
(docs/usage.md, "Changing moduli"). α = 8 is the value of dolfinx's P2 biharmonic demo; the tests
show that results change by less than the discretisation error for α in [4, 64] (test_penalty).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import ufl
from dolfinx import fem

from fabricsurf.discretise.constraints import AUGMENTATION, Multiplier
from fabricsurf.discretise.jit_keys import stable_constant_order, wait_for_other_compiles
from fabricsurf.discretise.quadrature import (
    CELL_QUADRATURE_DEGREE,
    FACET_QUADRATURE_DEGREE,
    FIBRE_TREATMENTS,
    REDUCED_FIBRE_DEGREE,
    reduced_measures,
)
from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.term_constants import TermConstants
from fabricsurf.model.terms import Term

Bound = list[tuple[Term, TermConstants]]
"""The terms of a model with the constants of one form."""

DEFAULT_PENALTY = 8.0
BOW_PENALTY = 1e4
"""β of :meth:`EnergyForm.bow_penalty`, relative to the other first-gradient moduli times h²."""
EVERYWHERE = "everywhere"
"""The facet tag of ``normal_derivative`` for the whole boundary (UFL's unmarked ``ds``)."""


def placement(u):
    """r = X + u with X the reference position embedded in R^d (z = 0 when d = 3)."""
    x = ufl.SpatialCoordinate(u.ufl_function_space().mesh)
    d = ufl.shape(u)[0]
    X = ufl.as_vector([x[0], x[1]] + [0.0] * (d - 2))
    return X + u


def kinematics(u, L, M) -> Kinematics:
    """Kinematics of the placement r = X + u with broken second gradient."""
    r = placement(u)
    return Kinematics(ufl.grad(r), ufl.grad(ufl.grad(r)), L, M)


def strain_energy_density(bound: Bound, kin: Kinematics):
    """W = Σ_terms density (per unit reference area)."""
    return sum(t.density(kin, c) for t, c in bound)


def membrane_scale(bound: Bound, kin: Kinematics):
    """Sum of the first-gradient moduli of the unconstrained terms (UFL, N/mm)."""
    return sum(
        (
            c[q]
            for t, c in bound
            if t.order == 1 and not t.constraints(kin, c)
            for q in t.parameters()
        ),
        0.0,
    )


def has_second_gradient(model: list[Term]) -> bool:
    return any(t.order == 2 for t in model)


def stiffness_scale(bound: Bound):
    """S: sum of the second-gradient moduli (UFL, from the form's constants)."""
    return sum(t.stiffness_scale(c) for t, c in bound if t.order == 2)


def double_force(bound: Bound, kin: Kinematics):
    """M = ∂W/∂H (d×2×2) of the second-gradient terms (Steigmann & dell'Isola 2015 eq. 82)."""
    H = ufl.variable(kin.H)
    k = Kinematics(kin.F, H, kin.L, kin.M)
    W2 = sum(t.density(k, c) for t, c in bound if t.order == 2)
    return ufl.diff(W2, H)


def contract_nn(Mt, n):
    """M_nn = M[i, a, b] n_a n_b (the edge double force of eq. 94)."""
    i, a, b = ufl.indices(3)
    return ufl.as_vector(Mt[i, a, b] * n[a] * n[b], i)


@dataclass
class EnergyForm:
    """Builder of the discrete energy functional on a mesh with facet tags.

    ``normal_derivative`` maps a facet tag (or EVERYWHERE) to the prescribed ∂_n u there (a UFL
    d-vector; the zero vector for a clamp). ``tractions`` maps a facet tag to a dead load t (per
    unit reference length, N/mm). ``bound`` pairs each term with the constants this form owns.
    """

    model: list[Term]
    u: object
    L: object
    M: object
    facet_tags: object = None
    normal_derivative: dict = field(default_factory=dict)
    tractions: dict = field(default_factory=dict)
    penalty: float = DEFAULT_PENALTY
    qdeg_cell: int = CELL_QUADRATURE_DEGREE
    qdeg_facet: int = FACET_QUADRATURE_DEGREE
    fibre_treatment: str = "full"

    def __post_init__(self) -> None:
        if self.fibre_treatment not in FIBRE_TREATMENTS:
            raise ValueError(
                f"fibre_treatment = {self.fibre_treatment!r} must be one of "
                f"{', '.join(FIBRE_TREATMENTS)}"
            )
        stable_constant_order()  # before the moduli's Constants are made (jit_keys)
        wait_for_other_compiles()
        msh = self.u.function_space.mesh
        self.bound: Bound = [(t, t.constants(msh)) for t in self.model]
        self.alpha = fem.Constant(msh, float(self.penalty))
        self.kin = kinematics(self.u, self.L, self.M)
        scale = AUGMENTATION * membrane_scale(self.bound, self.kin)
        self.multipliers = [
            Multiplier(name, g, r + scale, msh, self.term_degree(t))
            for t, c in self.bound
            for name, g, r in t.constraints(self.kin, c)
        ]
        self.dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": self.qdeg_cell})
        if self.reduced:
            self.dx, self.dx_fibre = reduced_measures(msh, self.qdeg_cell)
        md = {"quadrature_degree": self.qdeg_facet}
        self.dS = ufl.Measure("dS", domain=msh, metadata=md)
        self.ds = ufl.Measure("ds", domain=msh, subdomain_data=self.facet_tags, metadata=md)

    def constants_of(self, term: Term) -> TermConstants:
        """The constants of ``term`` (the very object, one of :attr:`model`) in this form."""
        for t, c in self.bound:
            if t is term:
                return c
        raise ValueError(
            f"term '{term.name}' is not one of this form's terms; a test builds "
            "its forms from its own copies of the terms it was given: use those "
            "(test.model)"
        )

    @property
    def reduced(self) -> bool:
        return self.fibre_treatment == "reduced"

    def term_degree(self, term: Term) -> int:
        """The cell quadrature degree of a term's energy (and of its constraints)."""
        return REDUCED_FIBRE_DEGREE if self.reduced and term.fibre else self.qdeg_cell

    @property
    def tension_degree(self) -> int:
        """The quadrature degree at which the fibre tensions are defined: that of the fibre
        terms (their multipliers live there; under the reduced treatment, elsewhere in the
        cell the elastic tension k(λ − 1) is not the one the energy carries)."""
        return REDUCED_FIBRE_DEGREE if self.reduced else self.qdeg_cell

    def cell_energy(self):
        if not self.reduced:
            W = strain_energy_density(self.bound, self.kin)
            W += sum(m.energy_density() for m in self.multipliers)
            if self.multipliers:
                W += self.bow_penalty()
            return W * self.dx
        dx_f = self.dx_fibre
        form = 0
        for t, c in self.bound:
            density = t.density(self.kin, c)
            if not (isinstance(density, float) and density == 0.0):
                form += density * (dx_f if t.fibre else self.dx)
        for m in self.multipliers:
            form += m.energy_density() * (dx_f if m.degree == REDUCED_FIBRE_DEGREE else self.dx)
        return form

    def bow_penalty(self):
        """½ β S_m h² |H|² per cell, with S_m :func:`membrane_scale` and β :data:`BOW_PENALTY`:
        a term that vanishes wherever exact fibre constraints hold.

        λ = μ = 1 at a P2 cell's quadrature points makes the cell affine (a quadratic curve of
        constant speed is a straight line), so H = 0 there at the constrained solution. A
        fibre edge bowed sideways by δ is stretched only as δ², which the multipliers hold at
        second order only, and their iteration stalled (docs/theory.md, "Exact
        inextensibility"). The term holds the bow at first order instead, without moving the
        solution: the force changes by less than 1e-6 for β from 10 to 1e5."""
        h = ufl.CellDiameter(self.u.function_space.mesh)
        scale = BOW_PENALTY * membrane_scale(self.bound, self.kin)
        return 0.5 * scale * h**2 * ufl.inner(self.kin.H, self.kin.H)

    def tension_fields(self) -> dict:
        """Fibre tensions per unit reference width (N/mm, UFL): the multipliers of exact
        constraints, else ∂W/∂λ and ∂W/∂μ of the elastic fibre terms."""
        fields = {m.name: m.tension() for m in self.multipliers}
        for t, c in self.bound:
            fields.update(t.tensions(self.kin, c))
        return fields

    def double_force(self):
        """M = ∂W/∂H of this form's second-gradient terms (UFL, with its constants)."""
        return double_force(self.bound, self.kin)

    def _ip_pieces(self):
        """(measure, jump, M_nn, S, h) of the C0-IP and Nitsche terms; jump is affine in u."""
        if not has_second_gradient(self.model):
            return []
        msh = self.u.function_space.mesh
        n, h = ufl.FacetNormal(msh), ufl.CellDiameter(msh)
        Mt = self.double_force()
        S = stiffness_scale(self.bound)
        F = self.kin.F
        jump = F("+") * n("+") + F("-") * n("-")
        avg_Mnn = 0.5 * (contract_nn(Mt("+"), n("+")) + contract_nn(Mt("-"), n("-")))
        S_facet = ufl.max_value(S("+"), S("-"))
        pieces = [(self.dS, jump, avg_Mnn, S_facet, 0.5 * (h("+") + h("-")))]
        for tag, g in self.normal_derivative.items():
            pieces.append((self.ds(tag), ufl.grad(self.u) * n - g, contract_nn(Mt, n), S, h))
        return pieces

    def _penalty_energy(self):
        return sum(
            self.alpha * S / (2 * h) * ufl.dot(j, j) * m for m, j, _, S, h in self._ip_pieces()
        )

    def _consistency_energy(self):
        return sum(-ufl.dot(j, Mnn) * m for m, j, Mnn, _, _ in self._ip_pieces())

    def load_potential(self):
        form = 0
        for tag, t in self.tractions.items():
            form += ufl.dot(t, self.u) * self.ds(tag)
        return form

    def internal(self):
        """Π_h without the external load potential (its variation gives the internal forces)."""
        Pi = self.cell_energy()
        if has_second_gradient(self.model):
            Pi += self._penalty_energy() + self._consistency_energy()
        return Pi

    def total(self):
        """Π_h as one UFL form."""
        return self.internal() - self.load_potential() if self.tractions else self.internal()

    def residual(self, v, internal_only: bool = False):
        """dΠ_h/du [v], exactly (the consistency term differentiated by ``ufl.derivative``)."""
        Pi = self.internal() if internal_only else self.total()
        return ufl.derivative(Pi, self.u, v)

    def jacobian(self, du, v):
        """d²Π_h/du² [du, v] less the term [[∂_n r]]·{D²M_nn[du, v]}.

        That term is a third derivative of W multiplied by the gradient jump, which vanishes at
        the exact solution; dropping it keeps the generated kernels (and their compile time)
        an order of magnitude smaller, while the residual stays the exact variation of Π_h.
        Newton then converges superlinearly rather than quadratically (measured in
        benchmarks/solve.py).
        """
        smooth = self.cell_energy() - (self.load_potential() if self.tractions else 0)
        if has_second_gradient(self.model):
            smooth += self._penalty_energy()
        a = ufl.derivative(ufl.derivative(smooth, self.u, v), self.u, du)
        for m, j, Mnn, _, _ in self._ip_pieces():
            dj_v = ufl.derivative(j, self.u, v)
            dj_du = ufl.derivative(j, self.u, du)
            a += (
                -(
                    ufl.dot(dj_v, ufl.derivative(Mnn, self.u, du))
                    + ufl.dot(dj_du, ufl.derivative(Mnn, self.u, v))
                )
                * m
            )
        return a
