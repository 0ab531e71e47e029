"""What the hemisphere plug-in (experiments/hemisphere.py) reads off the formed blank: the
forces, energies, dissipation and area fractions of the whole blank (reduced over ranks, times
the copies of the solved domain), the largest penetration and shear, the contact's active set,
the fields it writes, profiles along a ray from the pole (the shear, with the arc length over
the punch and the gap to it) and the element midpoints on the aligned quarter's diagonal. A
mix-in: the plug-in builds the forms and fields; these methods only evaluate them, apart from
its set-up and load path."""

from __future__ import annotations

import math

import numpy as np
from dolfinx import fem
from dolfinx.mesh import compute_midpoints
from mpi4py import MPI

from fabricsurf.discretise.energy import CELL_QUADRATURE_DEGREE
from fabricsurf.discretise.evaluation import (
    eval_points,
    interpolate_expression,
    max_over_cells,
    nodal_average,
    quadrature_expression,
)
from fabricsurf.discretise.output import FieldWriter
from fabricsurf.experiments.forming import blank as forming_blank
from fabricsurf.geometry.aligned import lattice_divisions, square_divisions
from fabricsurf.model.kinematics import l_dir, m_dir


class BlankOutputs:
    """The readings of a formed blank (module docstring), for a plug-in that holds:
    ``problem`` and ``solver`` (the contact problem and its Newton solver), ``specimen``,
    ``setup``, ``comm``, ``tools``, ``r`` (the placement), ``indicators`` and ``wrinkling``,
    ``pins`` (the full blank's pinned dofs), ``copies`` (4 for the quarter, else 1) and the
    compiled forms and expressions ``_forms`` (force, stored, tools, wrinkle, locked),
    ``_pen`` (penetration into each tool), ``_pen_q`` and ``_gamma_q`` (at the quadrature
    points)."""

    def pin_reactions(self) -> dict[str, float]:
        """The force each pin of the full blank exerts (N, the residual's virtual work on a
        unit motion of the pinned dof, reduced over ranks): zero when the pins remove only
        motions the answer does not have."""
        out = {}
        for name, dofs in self.pins.items():
            w = fem.Function(self.problem.V)
            w.x.array[dofs] = 1.0
            out[name] = self.solver.virtual_work(w)
        return out

    # -- reduced scalars (whole blank) ---------------------------------------------------
    def _scalar(self, name: str) -> float:
        for table in self.tools.tables:  # tools given as surfaces, at the state as it is now
            table.refresh()
        return self.copies * float(
            self.comm.allreduce(fem.assemble_scalar(self._forms[name]), op=MPI.SUM)
        )

    def reaction(self) -> float:
        """The punch force F = ∂Π/∂s (N, forming_tools.py), reduced over ranks."""
        return self._scalar("force")

    def energies(self) -> tuple[float, float]:
        """(stored energy, tools' energy: the contact penalty, the holder's potential and the
        self-weight's) of the whole blank (N·mm); their sum is the total energy Π of the work
        balance."""
        return self._scalar("stored"), self._scalar("tools")

    def dissipated(self) -> float:
        """The energy dissipated by friction on the tools since the start of :meth:`run`
        (N·mm, whole blank): with it the work balance reads ∫ F ds = ΔΠ + D."""
        return self.copies * self.solver.dissipated

    def damped(self) -> float:
        """The energy dissipated by the viscous stabilisation since the start of :meth:`run`
        (N·mm, whole blank; 0 when it is off): ∫ F ds = ΔΠ + D + D_v."""
        return self.copies * self.solver.damped

    def area_fractions(self) -> dict[str, float]:
        """Fractions of the blank's reference area that wrinkle and that are beyond locking."""
        area = forming_blank.area(self.setup)
        return {"wrinkle": self._scalar("wrinkle") / area, "locked": self._scalar("locked") / area}

    def max_penetration(self, tool: str = "punch") -> float:
        """Largest penetration into a tool at the contact energy's quadrature points (mm)."""
        expr = (
            self._pen_q
            if tool == "punch"
            else quadrature_expression(self._pen[tool], self.specimen.mesh, CELL_QUADRATURE_DEGREE)
        )
        return max_over_cells(expr, self.specimen.mesh)

    def max_shear_deg(self) -> float:
        """max |γ| over the quadrature points of all ranks (deg)."""
        return math.degrees(max_over_cells(self._gamma_q, self.specimen.mesh))

    def most_sheared(self) -> tuple[float, float]:
        """The reference (X, Y) of the midpoint of the cell with the largest |γ| (mm; the
        same on every rank): where a net that shears too far does so."""
        msh = self.specimen.mesh
        cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
        mine = (-1.0, 0.0, 0.0)
        if len(cells):
            gamma = np.abs(self._gamma_q.eval(cells)).max(axis=1)
            k = int(np.argmax(gamma))
            X = compute_midpoints(msh, 2, cells[k : k + 1])[0]
            mine = (float(gamma[k]), float(X[0]), float(X[1]))
        return max(self.comm.allgather(mine))[1:]

    def active_set(self) -> np.ndarray:
        """Whether each quadrature point of the owned cells penetrates the punch (this rank's
        points, flattened): compare two states to count the contact active-set changes."""
        cells = np.arange(self.specimen.mesh.topology.index_map(2).size_local, dtype=np.int32)
        return (self._pen_q.eval(cells) > 0.0).ravel()

    # -- fields and profiles ---------------------------------------------------------------
    def fields(self) -> dict:
        """Forming fields for FieldWriter(extra=...) (module docstring)."""
        kin = self.problem.energy.kin
        fl, fm = l_dir(kin.F, kin.L), m_dir(kin.F, kin.M)
        out = {
            "shear_deg": kin.gamma * (180.0 / math.pi),
            "contact_pressure": self.tools.pressure(self.r),
            "wrinkle": self.wrinkling.mark,
            "least_membrane_force": self.wrinkling.smoothed,
            "beyond_locking": self.indicators.locked(kin),
        }
        out.update(
            {f"{n}_{c}": v[i] for n, v in (("l", fl), ("m", fm)) for i, c in enumerate("xyz")}
        )
        out.update(self.problem.energy.tension_fields())
        return out

    def writer(self, path) -> FieldWriter:
        """An XDMF writer of u and the forming fields (the caller closes it)."""
        return FieldWriter(
            path,
            self.problem.u,
            self.problem.energy.kin,
            qdeg=CELL_QUADRATURE_DEGREE,
            extra=self.fields(),
        )

    def element_centres(self) -> np.ndarray:
        """Reference distances from the pole of the midpoints of the mesh edges on the diagonal
        (the fibres' bisector, the ray at the plug-in's ``diagonal_deg``). With stiff fibres the
        shear of the discrete sheet is nearly constant on each element of the aligned mesh (it
        behaves as a pin-jointed net of cell size h) and jumps between elements: there an
        element's value stands for its mean."""
        if self.theta is None or forming_blank.shape(self.setup) != "square":
            raise ValueError(
                "element_centres: only on the aligned quarter's mesh (a square "
                "blank with fibres at ±θ or 0/90)"
            )
        half = 0.5 * self.setup.length
        if self.theta == 0.0:
            d = half / square_divisions(half, self.h)
            return np.arange(0.5 * d, half, d) * math.sqrt(2.0)
        dx = half / lattice_divisions(half, half, self.h, self.theta)[0]
        return np.arange(dx, half, 2.0 * dx)

    def profile(
        self, direction_deg: float, X: np.ndarray | None = None, n: int = 40
    ) -> dict[str, np.ndarray]:
        """Along the reference ray from the pole at ``direction_deg`` (``diagonal_deg``:
        the fibres' bisector, the benchmarks' diagonal; a fibre's angle: that fibre), at
        reference distances ``X`` (default n points to the blank's edge): X, the arc length
        from the pole over the deformed sheet's polar angle about the punch centre, R·φ, the
        shear angle γ (deg), the recovered shear angle (deg: its area-weighted nodal average,
        evaluation.nodal_average, the continuous field a post-processor shows in place of the
        per-element staircase of a stiff net), and the gap to the punch's cap (mm; negative:
        penetration). The same on every rank."""
        t = math.radians(direction_deg)
        reach = forming_blank.reach(self.setup, direction_deg)
        X = np.linspace(0.0, reach, n) if X is None else np.asarray(X, dtype=float)
        n = len(X)
        pts = np.column_stack([X * math.cos(t), X * math.sin(t)])
        kin = self.problem.energy.kin
        gam = interpolate_expression(kin.gamma * (180.0 / math.pi), self._S)
        rec = nodal_average(
            kin.gamma * (180.0 / math.pi), self.specimen.mesh, CELL_QUADRATURE_DEGREE
        )
        r = np.column_stack([pts, np.zeros(n)]) + eval_points(self.problem.u, pts)
        r[:, 2] -= float(self.tools.stroke.value) - self.R
        dist = np.linalg.norm(r, axis=1)
        phi = np.arccos(np.clip(r[:, 2] / dist, -1.0, 1.0))
        return {
            "X": X,
            "arc": self.R * phi,
            "shear_deg": eval_points(gam, pts)[:, 0],
            "shear_recovered_deg": eval_points(rec, pts)[:, 0],
            "gap": np.where(r[:, 2] > 0, dist - self.R, np.inf),
        }
