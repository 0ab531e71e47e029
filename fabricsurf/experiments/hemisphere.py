"""Forming over a hemispherical punch (the woven-fabric hemisphere benchmark) as a 3D plug-in.

A blank (a square of side B = ``length`` = ``width`` mm by default; a rectangle or a circle:
forming/blank.py), centred on the punch axis, with fibres at ±θ to its sides or along them
(0°/90°) or any other pair, lies at z = 0 between a blank holder and a die with
an opening of radius R_o = R + clearance (or a rectangle with rounded corners:
forming/surfaces/opening.py); a rigid hemispherical punch of radius R (or any punch given as a
surface: forming/tabulated_tools.py), its pole at z = s (the stroke, the load path, mm), pushes
it up through the opening (forming/tools.py: signed distances, penalty contact, holder
friction, the punch force as the work conjugate of the stroke).

A set-up symmetric about the blank's mid-lines is solved on one quarter [0, L/2] × [0, W/2]
with mirror conditions, meshed along the fibres (geometry/aligned.py) so that stiff fibres do
not lock; other blanks and fibre pairs on the full blank, its rigid motions pinned
(forming/blank.py; which one: :attr:`discretisation`). Reported forces and energies are the
whole blank's. The stroke is followed by forming/contact_newton.py; options are checked before
any computation (forming/options.py); each converged step is logged (forming/stroke_log.py).
Outputs: the shear angle, fibre directions and tensions, normal curvatures, contact pressure,
the wrinkling indicator and the region beyond the locking angle (forming/indicators.py;
docs/forming.md).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.energy import placement
from fabricsurf.discretise.evaluation import quadrature_expression
from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE
from fabricsurf.discretise.stepping import LoadStepError, LoadStepper
from fabricsurf.errors import DataError, InputError
from fabricsurf.experiments.base import ExperimentPlugin, PluginSetup
from fabricsurf.experiments.forming import blank as forming_blank
from fabricsurf.experiments.forming import options as forming_options
from fabricsurf.experiments.forming.blank_outputs import BlankOutputs
from fabricsurf.experiments.forming.contact_newton import (
    FALLBACK,
    FULL_STEP_DIVERGENCE,
    FULL_STEP_ITERATIONS,
)
from fabricsurf.experiments.forming.fixed_tools import checked_punch, die_check
from fabricsurf.experiments.forming.indicators import Indicators, Wrinkling
from fabricsurf.experiments.forming.stroke_log import (
    StrokeLog,
    collapsed,
    stabilisation_share,
)
from fabricsurf.experiments.forming.tools import ContactProblem, Tools
from fabricsurf.geometry.aligned import blank_angle
from fabricsurf.log import warn
from fabricsurf.model.terms import Term

logger = logging.getLogger(__name__)


class HemispherePlugin(BlankOutputs, ExperimentPlugin):
    """Plug-in: a blank formed over a hemispherical punch (module docstring). Load path: the
    stroke s (mm); reaction: the punch force (N). What it reads off the formed blank (forces,
    energies, fields, profiles) is :class:`~.forming.blank_outputs.BlankOutputs`'s."""

    name = "hemisphere"
    d = 3
    path_label = "punch stroke (mm)"
    reaction_label = "punch force (N)"
    keys = {
        "tooling": {**forming_blank.KEYS, **forming_options.TOOL_KEYS},
        "material": forming_options.MATERIAL_KEYS,
    }

    def __init__(
        self,
        setup: PluginSetup,
        model: list[Term],
        h: float,
        comm: MPI.Comm = MPI.COMM_WORLD,
        snes_options: dict | None = None,
    ) -> None:
        super().__init__(setup, model, h, comm)
        o = setup.options
        self.check_specimen(setup, "hemisphere")
        forming_blank.check_mesh(setup, h, h == self.default_h(setup))
        sizes = {"lip": o["die_lip"]}  # a rectangular opening has no clearance of its own
        if forming_options.opening(o).kind == "circle":
            sizes = {"clearance": o["clearance"], **sizes}
        if h > min(sizes.values()):
            warn(
                logger,
                comm,
                f"hemisphere: h = {h:g} mm exceeds the die's {' or '.join(sizes)} "
                f"({', '.join(f'{v:g}' for v in sizes.values())} mm): the mesh does not resolve "
                "the tools and the punch force is not mesh-converged",
            )
        unheld = forming_blank.unheld_edge(setup)
        if unheld is not None:
            warn(logger, comm, unheld)
        self.R = o["punch_radius"]
        self.theta = blank_angle(tuple(setup.fibre_angles_deg))
        self.diagonal_deg = forming_blank.bisector_deg(tuple(setup.fibre_angles_deg))
        self.domain = forming_blank.domain(setup, h)
        self.copies = 4.0 if self.domain == "quarter" else 1.0
        self.specimen = forming_blank.blank_mesh(setup, self.domain, self.theta, h, comm)
        msh = self.specimen.mesh
        self.tools = Tools.from_options(msh, o)
        t, reach = self.tools.tabulated, self.stroke_limit(setup)
        surface = checked_punch(o) if t is None else t.surface
        self._die_check = None if surface is None else die_check(surface, o, reach)
        p = ContactProblem(
            self.specimen,
            self.model,
            self.tools,
            d=3,
            fibre_angles=tuple(setup.fibre_angles_deg),
            prefix="fabricsurf_hemisphere_",
            fallback=FALLBACK,
            snes_options={
                "snes_max_it": FULL_STEP_ITERATIONS,
                "snes_divergence_tolerance": FULL_STEP_DIVERGENCE,
                "snes_linesearch_type": "basic",
                **(snes_options or {}),
            },
        )
        p.mirror("clamp", 0)  # the full blank has no such edges: the same forms, no terms
        p.mirror("bottom", 1)
        self.pins, self.rotation_vertex = (
            ({}, None)
            if self.domain == "quarter"
            else forming_blank.pin_rigid_motions(
                p,
                self.R,
                not any(o.get(k, 0.0) for k in ("friction", "punch_friction", "die_friction")),
            )
        )
        self.discretisation = forming_blank.record(
            setup, self.specimen, self.domain, self.rotation_vertex, h
        )
        self.problem, self.solver = p, p.solver()
        self.r, kin = placement(p.u), p.energy.kin
        pen = self.tools.penetrations(self.r)
        self.indicators = Indicators.from_options(msh, o)
        self.wrinkling = Wrinkling(
            msh, self.r, kin, p.energy.tension_fields(), self.tools, self.model, p.dx
        )
        self._forms = {
            "force": self.tools.force_density(self.r) * p.dx,
            "stored": p.energy.internal(),
            "tools": p.contact_energy(),
            "wrinkle": self.wrinkling.mark * p.dx,
            "locked": self.indicators.locked(kin) * p.dx,
        }
        self._forms = {k: fem.form(v) for k, v in self._forms.items()}
        self._S = fem.FunctionSpace(msh, ("DG", 2))
        self._pen = pen
        self._gamma_q = quadrature_expression(abs(kin.gamma), msh, CELL_QUADRATURE_DEGREE)
        self._pen_q = quadrature_expression(pen["punch"], msh, CELL_QUADRATURE_DEGREE)
        self.stroke: list[float] = []
        self.force: list[float] = []
        self.steps: list[dict] = []

    @classmethod
    def parse_options(cls, tables: dict, length_scale: float, where: str) -> dict:
        return {
            **forming_options.parse(tables, length_scale, where),
            **forming_blank.parse(tables, where),
        }

    @classmethod
    def check_specimen(cls, setup: PluginSetup, where: str) -> None:
        forming_blank.check_specimen(setup, where)

    @classmethod
    def default_h(cls, setup: PluginSetup) -> float:
        return setup.options["punch_radius"] / 6.0

    bends = "hemisphere forming (the sheet bends over the punch and the die's lip)"
    field_not_compared = (
        "a displacement field of a formed part is not yet compared (its "
        "points would need mapping onto the solved quarter with the mirrored "
        "components); compare the punch force (force.csv) and the shear "
        "angles at points (shear.csv, docs/contracts.md)"
    )

    @classmethod
    def check_data(cls, setup: PluginSetup, steps, path, where: str) -> None:
        """The largest measured stroke within what the die and the blank allow."""
        i = int(max(range(len(path)), key=lambda j: path[j]))
        surface = checked_punch(setup.options)
        try:
            forming_blank.check_stroke(setup, float(path[i]))
            if surface is not None:
                die_check(surface, setup.options, float(path[i]))(float(path[i]))
        except InputError as err:
            raise DataError(f"{where}: step {int(steps[i])}: {err}") from None

    @classmethod
    def stroke_limit(cls, setup: PluginSetup) -> float:
        """The largest stroke the blank allows (forming_options.max_stroke)."""
        return forming_options.max_stroke(setup.options, 2.0 * forming_blank.inner_half(setup))

    @classmethod
    def check_path(cls, steps, path, where: str) -> None:
        """No stroke may be negative (the punch touches the flat blank at s = 0)."""
        for k, v in zip(steps, path):
            if not v >= 0:
                raise DataError(
                    f"{where}: step {int(k)}: punch stroke {v:g} mm is negative: "
                    "the punch starts touching the flat blank at 0 and pushes it "
                    "up into the die"
                )

    def check_stroke(self, stroke: float) -> None:
        """Refuse a stroke beyond what the die and the blank allow (forming_options), or one
        that drives a punch given as a surface into the die (fixed_tools.die_check)."""
        forming_blank.check_stroke(self.setup, stroke)
        if self._die_check is not None:
            self._die_check(stroke)

    def set_load(self, t: float) -> None:
        self.tools.stroke.value = float(t)

    def _release(self) -> None:
        super()._release()
        self.wrinkling.close()

    def run(
        self,
        stroke: float,
        steps: int = 8,
        on_step: Callable[[int, float], None] | None = None,
        label: str = "",
    ) -> list[int]:
        """Move the punch from s = 0 (touching the flat blank) to ``stroke`` in ``steps`` equal
        requested steps (cut on divergence, LoadStepper); records :attr:`stroke`,
        :attr:`force` and the step log :attr:`steps` (forming/stroke_log.StrokeLog) at each, and
        logs its line (PROGRESS) and every cut (DEBUG), prefixed with ``label``, as it happens.
        Returns the Newton iterations per step; raises LoadStepError (where it stopped) if a
        step cannot be followed, with :attr:`steps` holding the steps converged before."""
        self.check_stroke(stroke)
        self.solver.reset()
        self.set_load(0.0)
        self.stroke, self.force = [0.0], [0.0]
        if self.tools.softening:  # a softened punch presses the flat blank at s = 0 already
            self.solver.solve()
            self.force = [self.reaction()]
        book = StrokeLog(
            self.comm, self.active_set, lambda: self.solver.fallbacks, label, self.max_shear_deg
        )
        self.steps = book.records

        def done(k: int, s: float, its: int) -> None:
            self.stroke.append(s)
            self.force.append(self.reaction())
            self.wrinkling.update()
            book.step(k, s, self.force[-1], its, self.stepper.attempts[-1], steps)
            if on_step is not None:
                on_step(k, s)

        self.stepper = LoadStepper(self.solver, self.set_load, done, label=label)
        try:
            its = self.stepper.run(np.linspace(stroke / steps, stroke, steps))
        except LoadStepError as err:
            raise collapsed(err, self.steps, self.most_sheared) from err
        if self.tools.stabilisation:
            stabilisation_share(self.comm, self.stroke, self.force, self.damped(), label)
        return its

    # -- observations of the compare/fit/diagnose loop (docs/forming.md, "In the loop") -----
    takes_shear = True
    reaction_scales_with_moduli = False

    def reaction_form(self):
        """The punch force of the whole blank, ∫ k_c ⟨−d_p⟩ n_z dX (with the punch's friction
        traction, forming_friction.py) over the solved domain times :attr:`copies` (a UFL form;
        its value is :meth:`reaction`): the forward model differentiates it along du/dp (it
        does not depend on the moduli)."""
        return self.copies * self.tools.force_density(self.r) * self.problem.dx

    def shear_angle(self):
        """The shear angle γ (deg) as a UFL expression of u (the ``shear_deg`` output)."""
        return self.problem.energy.kin.gamma * (180.0 / math.pi)

    def shear_points(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Points of the whole blank (data frame: origin at the lower-left corner of its
        bounding box) in the solved domain's frame (origin on the punch axis), and the sign of
        γ there. The full blank: the points as they are, sign 1. The quarter: mapped onto it by
        the mid-lines' mirrors; ±θ fibres are swapped by a mirror (l·m and γ unchanged),
        0°/90° fibres have one family reversed by it (γ changes sign across each mid-line)."""
        centre = 0.5 * np.array([self.setup.length, self.setup.width])
        rel = np.asarray(X, dtype=float).reshape(-1, 2) - centre
        sign = np.ones(len(rel))
        if self.domain != "quarter":
            return rel, sign
        if self.theta == 0.0:
            sign = np.where(rel[:, 0] < 0, -1.0, 1.0) * np.where(rel[:, 1] < 0, -1.0, 1.0)
        return np.abs(rel), sign
