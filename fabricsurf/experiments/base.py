"""The experiment protocol: what a test must provide so that compare, fit and diagnose can use it.

An experiment plug-in is one class derived from :class:`ExperimentPlugin` (one file in
``fabricsurf/experiments/``) and one entry in the registry of :mod:`fabricsurf.experiments`.
From the experiment description (specimen, fibre angles, plug-in options) it builds the mesh,
the boundary conditions and the solver; :meth:`~ExperimentPlugin.set_load` applies one value of
the load path (one value per measured step); at a converged state the generic forward model
(:mod:`fabricsurf.inverse.forward.runs`) observes

* displacements at points: the d components of u (d = :attr:`~ExperimentPlugin.d`),
* the measured reaction as a virtual-work functional R(u)·w, with w =
  :meth:`~ExperimentPlugin.reaction_weight` the derivative of the prescribed boundary motion
  with respect to the load-path value (so edge and corner forces are included, and the
  sensitivity of the reaction is (∂R/∂p + K du/dp)·w); or, for a test whose reaction is not
  the work conjugate of a prescribed boundary motion (a rigid tool's force through a contact
  penalty: the hemisphere's punch), a general reaction functional F(u) =
  :meth:`~ExperimentPlugin.reaction_form` (a UFL form), with the sensitivity ∂F/∂p + (∂F/∂u)·du/dp,
* scalar fields at points (the shear angle of a formed part, as optical measurement gives it):
  :meth:`~ExperimentPlugin.shear_angle` and :meth:`~ExperimentPlugin.shear_points` (points of the
  whole specimen mapped onto the solved part by the set-up's symmetry).

Each plug-in validates its own keys of ``experiment.toml`` (:attr:`~ExperimentPlugin.keys`,
:meth:`~ExperimentPlugin.parse_options`); keys it does not declare are rejected by the loader.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.discretise.resources import Owner, release_vectors
from fabricsurf.discretise.solver import SNESSolver
from fabricsurf.errors import DataError
from fabricsurf.model.terms import Term


@dataclass
class PluginSetup:
    """What a plug-in needs to build its boundary-value problem (lengths in mm).

    ``options`` holds the plug-in's own validated keys (e.g. ``clamp``), already in mm and N.
    """

    test: str
    length: float
    width: float
    fibre_angles_deg: tuple[float, float]
    options: dict = field(default_factory=dict)


@dataclass
class Variant:
    """A variant of a test, as a separating experiment (:meth:`ExperimentPlugin.
    separating_variants`): its key and description, specimen, load path, fibre angles and,
    when it is another test, that test's name and options."""

    key: str
    description: str
    length: float
    width: float
    path: np.ndarray
    angles: tuple[float, float]
    test: str | None = None
    options: dict | None = None


class ExperimentPlugin(Owner, ABC):
    """Base class of the experiment plug-ins (module docstring).

    Class attributes: ``name`` (the ``[loading] test`` value), ``d`` (2: planar, 3: out of
    plane), ``path_unit`` ("length": the load path is a displacement converted with the length
    unit; "1": a dimensionless factor), ``has_reaction`` (whether a force column may be given),
    ``path_label``/``reaction_label`` (axis labels), ``keys`` ({table: {key: help}}: the
    plug-in's own keys of experiment.toml), ``takes_shear`` (whether measured shear angles at
    points may be given: :meth:`shear_angle`), ``reaction_scales_with_moduli`` (every modulus
    times c gives the same u and c times the reaction: a displacement-driven test without
    other stiffness; not so against a contact penalty and a holder's pressure), ``weak_terms``
    (effects whose moduli the test hardly determines: a fit's start scan leaves them at their
    given values instead of moving them by decades into values that break the forward model),
    ``bends`` (what the test is, if its answer needs a bending stiffness: a second-gradient
    term), ``field_not_compared`` (why a measured displacement field of this test is not yet
    compared, or None). :meth:`check_data` refuses measured data the test cannot follow and
    :meth:`separating_variants` names the test's own variants that may separate a tie;
    :meth:`zone_distance` measures how far points lie from its grips and zone boundaries (where
    a diagnosis locates the excess misfit).

    A plug-in owns its problem's PETSc objects: :meth:`close` (or ``with``) destroys them when
    a run ends (discretise/resources.py). It owns its terms too: :attr:`model` holds copies of
    those given (``Term.copy``), and a plug-in builds its forms, and reads moduli, from
    ``self.model``, never from the ``model`` argument: a forward model sets the moduli of
    ``self.model`` and the forms follow without recompiling.
    """

    name: ClassVar[str] = ""
    d: ClassVar[int] = 2
    path_unit: ClassVar[str] = "length"
    has_reaction: ClassVar[bool] = True
    takes_shear: ClassVar[bool] = False
    reaction_scales_with_moduli: ClassVar[bool] = True
    path_label: ClassVar[str] = "load path"
    reaction_label: ClassVar[str] = "reaction (N)"
    keys: ClassVar[dict[str, dict[str, str]]] = {}
    weak_terms: ClassVar[tuple[str, ...]] = ()
    bends: ClassVar[str] = ""
    field_not_compared: ClassVar[str | None] = None

    problem: FabricProblem
    solver: SNESSolver

    def __init__(
        self, setup: PluginSetup, model: list[Term], h: float, comm: MPI.Comm = MPI.COMM_WORLD
    ) -> None:
        self.setup, self.h, self.comm = setup, float(h), comm
        self.model: list[Term] = [t.copy() for t in model]
        """The plug-in's own terms (copies of those given): its forms are built from them, so a
        change of the given terms leaves it alone, and ``set`` on these changes it."""

    @classmethod
    def parse_options(cls, tables: dict, length_scale: float, where: str) -> dict:
        """Validate the plug-in's keys (``tables``: the TOML tables) into an options dict."""
        return {}

    @classmethod
    def check_specimen(cls, setup: PluginSetup, where: str) -> None:
        """Reject specimens the test cannot have (e.g. a non-square picture frame)."""

    @classmethod
    def check_path(cls, steps, path, where: str) -> None:
        """Reject load-path values (one per step, in mm or the factor) the test does not model.
        Default, a test driven by a displacement ("length"): it models extension (the
        specimen pulled), so no value may be negative."""
        if cls.path_unit != "length":
            return
        neg = [k for k, v in enumerate(path) if v < 0]
        if neg:
            k = neg[0]
            raise DataError(
                f"{where}: step {int(steps[k])}: {cls.path_label} {path[k]:g} is "
                f"negative; the '{cls.name}' test models extension (the specimen "
                "pulled, displacements ≥ 0), not compression"
            )

    @classmethod
    def check_data(cls, setup: PluginSetup, steps, path, where: str) -> None:
        """Refuse measured load-path values the test cannot follow (a stroke through the die),
        before any computation; default: none."""

    @classmethod
    def separating_variants(cls, setup: PluginSetup, path, first_gradient: bool) -> list[Variant]:
        """Variants of this test that may separate two tied effects (docs/diagnosis.md,
        "Separating a tie"), besides the generic ones (a larger displacement, a measured
        field); ``first_gradient``: whether the tie is between first-gradient effects."""
        return []

    @classmethod
    def zone_distance(cls, setup: PluginSetup, X) -> np.ndarray | None:
        """The distance (mm) of each reference point ``X`` (n×2, the data's frame) from the
        nearest clamp or boundary between the test's deformation zones: where the continuum
        meets what it cannot represent at the scale of the yarns (docs/diagnosis.md, "Where
        the excess sits"). None (the default): the test has no such zones."""
        return None

    @classmethod
    def default_h(cls, setup: PluginSetup) -> float:
        """Default element size (mm)."""
        return min(setup.length, setup.width) / 10.0

    @abstractmethod
    def set_load(self, t: float) -> None:
        """Apply the load-path value t (Constants / boundary values only: no recompilation)."""

    def reaction_weight(self) -> fem.Function | None:
        """w with reaction = R(u)·w (None when the test measures no reaction)."""
        return None

    def reaction_form(self):
        """A UFL form (a functional of the solution u, affine in the moduli) whose value is the
        measured reaction, for tests whose reaction is no virtual work R(u)·w; None (the
        default): the reaction is R(u)·w with :meth:`reaction_weight`."""
        return None

    def shear_angle(self):
        """The shear angle (deg) as a UFL expression of u, for tests whose data may hold
        measured shear angles at points (``shear.csv``, docs/contracts.md); None (the default):
        the test takes no shear data."""
        return None

    def shear_points(self, X):
        """(points of the solved domain, sign): the measured points ``X`` (n×2, the data's
        frame: origin at the specimen's lower-left corner) mapped onto the mesh, and the sign
        that carries the shear angle there to the measured point (a mirror may reverse it).
        Default: the mesh is the whole specimen in the data's frame."""
        X = np.asarray(X, dtype=float).reshape(-1, 2)
        return X, np.ones(len(X))

    def reaction(self) -> float:
        """The measured reaction at the current state (reduced over ranks)."""
        w = self.reaction_weight()
        if w is None:
            raise ValueError(f"experiment '{self.name}' has no reaction")
        return self.solver.virtual_work(w)

    def _release(self) -> None:
        problem = getattr(self, "problem", None)
        if problem is not None:
            problem.close()
            release_vectors(self.reaction_weight())


def choice_option(
    tables: dict, table: str, key: str, allowed: tuple[str, ...], default: str, where: str
) -> str:
    """A string option that must be one of ``allowed`` (default when absent)."""
    value = tables.get(table, {}).get(key, default)
    if not isinstance(value, str) or value not in allowed:
        raise DataError(f"{where}: [{table}] {key} = {value!r} is not one of {list(allowed)}")
    return value


def number_option(
    tables: dict,
    table: str,
    key: str,
    where: str,
    default: float | None = None,
    positive: bool = True,
) -> float:
    """A finite (positive) number option; required when ``default`` is None."""
    t = tables.get(table, {})
    if key not in t:
        if default is None:
            raise DataError(f"{where}: missing key [{table}] {key}")
        return float(default)
    v = t[key]
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    if not ok or (positive and v <= 0):
        need = "a positive finite number" if positive else "a finite number"
        raise DataError(f"{where}: [{table}] {key} = {v!r} must be {need}")
    return float(v)
