"""A fabric boundary-value problem: space, model, boundary data, solver and reactions."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from functools import partial

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from fabricsurf.discretise.energy import (
    DEFAULT_PENALTY,
    EVERYWHERE,
    EnergyForm,
    has_second_gradient,
)
from fabricsurf.discretise.jit_keys import (
    mark_equispaced,
    stable_constant_order,
    wait_for_other_compiles,
)
from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE
from fabricsurf.discretise.resources import Owner, release_vectors, weak_method
from fabricsurf.discretise.solver import SNESSolver
from fabricsurf.model.kinematics import fibre_directions
from fabricsurf.model.terms import Term


def second_gradient_off(model: list[Term]) -> bool:
    """Every parameter of every second-gradient term of ``model`` is zero, so that their
    densities, the double force M and with it the interior-penalty and Nitsche terms (S = 0)
    vanish identically: each is proportional to the moduli (a user's term is checked to be
    linear in them). A term with a parameter that is not a modulus (an angle, a shape
    parameter) is never all zero in practice, and counts as on."""
    return all(getattr(t, p) == 0.0 for t in model if t.order == 2 for p in t.parameters())


class FabricProblem(Owner):
    """Displacement u = r − X in a degree-2 vector Lagrange space of dimension d on a specimen.

    Boundary data are added with :meth:`fix` (positions), :meth:`clamp_gradient` (zero normal
    derivative, weakly), :meth:`add_traction` and :meth:`add_point_force`; then
    :meth:`solver` builds the SNES solver. Prescribed values are fem.Constants, so they can be
    changed during load stepping without recompiling. :meth:`close` destroys the solver's PETSc
    objects (discretise/resources.py). ``fibre_treatment`` (``full`` or ``reduced``,
    :data:`~fabricsurf.discretise.quadrature.FIBRE_TREATMENTS`) is how the fibre terms are
    integrated.
    """

    def __init__(
        self,
        specimen,
        model: list[Term],
        d: int = 2,
        degree: int = 2,
        fibre_angles: tuple[float, float] = (45.0, -45.0),
        penalty: float = DEFAULT_PENALTY,
        snes_options: dict | None = None,
        prefix: str | None = None,
        fibre_treatment: str = "full",
    ) -> None:
        if d not in (2, 3):
            raise ValueError(f"d = {d}: the placement lives in R^2 or R^3")
        self.specimen, self.model, self.d = specimen, list(model), d
        stable_constant_order()  # before the fibre directions' Constants (EnergyForm repeats it)
        wait_for_other_compiles()
        self.msh = mark_equispaced(specimen.mesh)
        self.comm = self.msh.comm
        self.V = fem.VectorFunctionSpace(self.msh, ("CG", degree), dim=d)
        self.u = fem.Function(self.V, name="u")
        self.L, self.M = fibre_directions(*fibre_angles, msh=self.msh)
        self.penalty, self.snes_options, self.prefix = penalty, snes_options or {}, prefix
        self.fibre_treatment = fibre_treatment
        self.bcs: list = []
        self.normal_derivative: dict = {}
        self.tractions: dict = {}
        self._point_forces: list = []
        self.body_forces: list = []
        self._body_form = None
        self._solver: SNESSolver | None = None
        self.energy: EnergyForm | None = None
        self.cheap_energy: EnergyForm | None = None

    # -- boundary data -------------------------------------------------------------------
    def _open(self, what: str) -> None:
        """Boundary data are compiled into the solver's forms and vectors when it is built:
        adding more afterwards would be silently ignored, so it is an error."""
        if self._solver is not None:
            raise RuntimeError(
                f"FabricProblem.{what}: the solver was already built; add all "
                "boundary data and loads before calling solver()"
            )

    def edge_facets(self, edge: str) -> np.ndarray:
        tag = self.specimen.edge_tags[edge]
        return self.specimen.facet_tags.find(tag)

    def component_dofs(self, edge: str, i: int) -> np.ndarray:
        return fem.locate_dofs_topological(self.V.sub(i), 1, self.edge_facets(edge))

    def fix(self, edge: str, values: Sequence[float | None]) -> list[fem.Constant]:
        """Prescribe displacement components on an edge (None leaves a component free).

        Returns the fem.Constants holding the values (one per prescribed component).
        """
        self._open("fix")
        consts = []
        for i, val in enumerate(values):
            if val is None:
                continue
            c = fem.Constant(self.msh, float(val))
            self.bcs.append(fem.dirichletbc(c, self.component_dofs(edge, i), self.V.sub(i)))
            consts.append(c)
        return consts

    def fix_function(self, edge_or_facets, g: fem.Function) -> None:
        """Prescribe u = g (a Function in V) on an edge name or an array of facets."""
        self._open("fix_function")
        facets = (
            self.edge_facets(edge_or_facets) if isinstance(edge_or_facets, str) else edge_or_facets
        )
        self.bcs.append(fem.dirichletbc(g, fem.locate_dofs_topological(self.V, 1, facets)))

    def clamp_gradient(self, edge: str | None, g=None) -> None:
        """Prescribe ∂_n u = g (default 0: the clamp of Barchiesi et al. 2020 eq. 7) weakly on an
        edge, or on the whole boundary if ``edge`` is None.

        Each clamped edge gets its own facet kernel, holding the double force of the model and
        its derivative; one clamp on the whole boundary compiles one kernel instead of one per
        edge.
        """
        self._open("clamp_gradient")
        zero = ufl.as_vector([0.0] * self.d)
        tag = EVERYWHERE if edge is None else self.specimen.edge_tags[edge]
        self.normal_derivative[tag] = zero if g is None else g

    def add_traction(self, edge: str, t) -> None:
        """Dead load t (UFL d-vector, force per reference length) on an edge."""
        self._open("add_traction")
        self.tractions[self.specimen.edge_tags[edge]] = t

    def add_body_force(self, b) -> None:
        """Dead load b per unit reference area (UFL d-vector, N/mm², e.g. self-weight; build it
        from fem.Constants so that load stepping changes values only); potential −∫ b·u dx.

        Its work ∫ b·v dx is assembled as a load vector, like the point forces, rather than
        added to the residual form: ``SNESSolver.internal_force`` then stays the internal force,
        linear in the moduli, which the reactions and the exact modulus sensitivities
        (∂R/∂p = R with the moduli e_p, inverse/forward.py) rely on.
        """
        self._open("add_body_force")
        self.body_forces.append(b)

    def vertex_nodes(self, point: Sequence[float]) -> np.ndarray:
        """Local (block) indices of the dof nodes at a mesh vertex, ghosts included."""
        x = np.asarray(point, dtype=float)
        Vc, parent = self.V.sub(0).collapse()
        local = fem.locate_dofs_geometrical(
            Vc, lambda X: np.isclose(X[0], x[0]) & np.isclose(X[1], x[1])
        )
        return np.asarray(parent)[local] // self.V.dofmap.index_map_bs

    def fix_point(self, point: Sequence[float], values: Sequence[float]) -> list[fem.Constant]:
        """Prescribe all components of u at a mesh vertex; returns their fem.Constants."""
        self._open("fix_point")
        nodes, bs = self.vertex_nodes(point), self.V.dofmap.index_map_bs
        consts = []
        for i, val in enumerate(values):
            c = fem.Constant(self.msh, float(val))
            dofs = (nodes * bs + i).astype(np.int32)
            self.bcs.append(fem.dirichletbc(c, dofs, self.V.sub(i)))
            consts.append(c)
        return consts

    def add_point_force(self, point: Sequence[float], f: Sequence[float] | fem.Constant) -> None:
        """Dead point force f at a mesh vertex (e.g. a corner force f_i of Steigmann & dell'Isola
        2015 eq. 94)."""
        self._open("add_point_force")
        nodes = self.vertex_nodes(point)
        owned = nodes[nodes < self.V.dofmap.index_map.size_local]
        if self.msh.comm.allreduce(len(owned)) != 1:
            raise ValueError(f"point force at {tuple(point)}: not exactly one mesh vertex there")
        self._point_forces.append((owned, f, self.V.dofmap.index_map_bs))

    def _nodal_forces(self):
        """(local dofs, values) of the dead loads assembled outside the residual form: point
        forces and body forces, summed into one local array (ghost entries included, before
        the reverse scatter of SNESSolver._F), so loads at the same dof add up."""
        im, bs = self.V.dofmap.index_map, self.V.dofmap.index_map_bs
        f = (
            fem.assemble_vector(self._body_form).array.copy()
            if self._body_form is not None
            else np.zeros((im.size_local + im.num_ghosts) * bs)
        )
        for nodes, fp, bs in self._point_forces:
            fv = np.asarray(fp.value if isinstance(fp, fem.Constant) else fp, dtype=float)
            for i in range(self.d):
                np.add.at(f, nodes * bs + i, fv[i])
        return np.arange(len(f), dtype=np.int32), f

    # -- solving -------------------------------------------------------------------------
    def solver(self) -> SNESSolver:
        """The SNES solver of Π_h (built once)."""
        if self._solver is None:
            self.energy = EnergyForm(
                self.model,
                self.u,
                self.L,
                self.M,
                self.specimen.facet_tags,
                self.normal_derivative,
                self.tractions,
                self.penalty,
                fibre_treatment=self.fibre_treatment,
            )
            v, du = ufl.TestFunction(self.V), ufl.TrialFunction(self.V)
            if self.body_forces:
                dx = ufl.Measure(
                    "dx", domain=self.msh, metadata={"quadrature_degree": CELL_QUADRATURE_DEGREE}
                )
                self._body_form = fem.form(sum(ufl.dot(b, v) for b in self.body_forces) * dx)
            F, J = self._with_extra(self.energy, v, du)
            self._solver = self._new_solver(
                F,
                J,
                weak_method(self._nodal_forces) if self._point_forces or self.body_forces else None,
            )
            if has_second_gradient(self.model) and not self.energy.multipliers:
                first = [t for t in self.model if t.order == 1]
                # kept: the terms reach its constants through weak references only
                self.cheap_energy = replace(self.energy, model=first)
                self._solver.add_cheap_forms(
                    *self._with_extra(self.cheap_energy, v, du),
                    partial(second_gradient_off, self.model),
                )
        return self._solver

    def _with_extra(self, energy: EnergyForm, v, du) -> tuple:
        """(residual, Jacobian) of ``energy`` and of :meth:`extra_energy`."""
        F, J = energy.residual(v), energy.jacobian(du, v)
        extra = self.extra_energy()
        if extra is not None:
            dP = ufl.derivative(extra, self.u, v)
            F, J = F + dP, J + ufl.derivative(dP, self.u, du)
        return F, J

    def extra_energy(self):
        """An energy a subclass adds to Π_h (e.g. the penalty of contact with rigid tools);
        None: nothing is added."""
        return None

    def _new_solver(self, F, J, nodal_forces) -> SNESSolver:
        """The solver of residual F and Jacobian J (a subclass may return a SNESSolver
        subclass)."""
        return SNESSolver(
            F,
            J,
            self.u,
            self.bcs,
            self.prefix,
            self.snes_options,
            nodal_forces,
            self.energy.multipliers,
        )

    def solve(self) -> tuple[int, int]:
        return self.solver().solve()

    def _release(self) -> None:
        if self._solver is not None:
            self._solver.close()
        release_vectors(self.u)

    def reaction(self, edge: str, component: int = 0) -> float:
        """Total reaction on an edge along a component: R·v with v = 1 on its dofs (virtual
        work), so forces carried by edge and corner dofs are included. Reduced over ranks."""
        w = fem.Function(self.V)
        w.x.array[self.component_dofs(edge, component)] = 1.0
        return self.solver().virtual_work(w)


def boundary_facets(msh) -> np.ndarray:
    """All exterior facets of a mesh."""
    return dmesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
