"""The base class of the energy terms (the vocabulary itself is in ``terms.py``; ``yarn_slip`` in
``slip.py``): a named energy density per unit reference area with validated, non-negative moduli,
units, and what it tells about itself (order, whether it stretches the fibres, whether planar data
can see it, its shear moment in the bias test's three-zone estimate).

Every form built from a term owns the ``fem.Constant``\\ s of its moduli, on its own mesh
(fabricsurf/model/term_constants.py); :meth:`Term.set` changes them in every live form built
from that very term object, without recompiling any. A test or a forward model builds its forms
from its own copy of the terms it is given (:meth:`Term.copy`), so changing a user's term
changes the tests built after it, never one built before (docs/usage.md, "Changing moduli").
A term pickles and copies as its moduli and options alone, without live forms.
"""

from __future__ import annotations

import copy as _copy
import math
import weakref
from dataclasses import dataclass, field, fields
from typing import ClassVar

import numpy as np
from dolfinx import fem

from fabricsurf.model import pure_shear
from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.pure_shear import BIAS_ANGLES
from fabricsurf.model.term_constants import Params, TermConstants


@dataclass
class Term:
    """Base class: a named energy density with finite moduli, non-negative unless named in
    ``signed`` (the coefficient of a coupling, which may have either sign).

    Changing moduli: :meth:`set` changes the term and the constants of every live form built
    from this very object (no recompilation). The owners of forms (an experiment plug-in, a
    :class:`~fabricsurf.experiments.bias_extension.BiasExtension`, a forward model) build them
    from their own copies (:meth:`copy`, exposed as their ``model``), so ``set`` on the terms a
    user handed them changes only what is built from those terms afterwards; to change an
    existing test, set its own terms (``test.model``); a fit sets its forward model's. A term
    pickles and copies (:meth:`copy`, :func:`copy.copy`, :func:`copy.deepcopy`) as its fields
    alone: an equal term with no live forms."""

    name: ClassVar[str] = ""
    order: ClassVar[int] = 1  # 1: depends on F only; 2: depends on the second gradient H
    units: ClassVar[dict[str, str]] = {}
    options: ClassVar[tuple[str, ...]] = ()  # fields that are switches, not moduli
    monotonic_only: ClassVar[bool] = False  # an elastic stand-in for a dissipative effect
    fibre: ClassVar[bool] = False  # stretches the fibres (integrated apart when "reduced")
    in_plane: ClassVar[bool] = True  # acts on planar placements: planar (2D) data can see it
    signed: ClassVar[tuple[str, ...]] = ()  # moduli that may be negative (a coupling's)
    _live: weakref.WeakSet = field(
        default_factory=weakref.WeakSet, init=False, repr=False, compare=False
    )  # the constants of the live forms (set())

    def __post_init__(self) -> None:
        for p in self.parameters():
            self._check(p, getattr(self, p))

    def copy(self) -> Term:
        """An equal term (moduli and options) with no live forms: :meth:`set` on either
        leaves the other and its forms alone."""
        return _copy.deepcopy(self)

    def __getstate__(self) -> dict:
        """The fields (and any other attribute) without the weak references to live forms,
        which neither pickle nor belong to a copy."""
        state = dict(self.__dict__)
        state.pop("_live", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._live = weakref.WeakSet()

    @classmethod
    def parameters(cls) -> list[str]:
        return [
            f.name for f in fields(cls) if not f.name.startswith("_") and f.name not in cls.options
        ]

    def _check(self, p: str, value: float) -> None:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"term '{self.name}': parameter {p} = {value!r} is not a number")
        if not math.isfinite(v) or (v < 0.0 and p not in self.signed):
            raise ValueError(
                f"term '{self.name}': parameter {p} = {value!r} must be finite"
                f"{'' if p in self.signed else ' and >= 0'} ({self.units.get(p, '')})"
            )

    def constants(self, msh) -> TermConstants:
        """New UFL objects of the parameters on mesh ``msh``, for one form to own.

        Each form gets its own (one model may serve several experiments, on several meshes);
        the term keeps a weak reference to them for :meth:`set`."""
        consts = TermConstants({p: self.parameter_on(msh, p) for p in self.parameters()})
        self._live.add(consts)
        return consts

    def parameter_on(self, msh, name: str) -> fem.Constant | fem.Function:
        """The UFL object of parameter ``name`` on ``msh``: a fem.Constant (a term whose
        parameter varies from cell to cell returns a field)."""
        return fem.Constant(msh, float(getattr(self, name)))

    def set(self, **values: float) -> None:
        """Change moduli, in the constants of every live form built from this term object too
        (no recompilation); not in those of a copy (the class docstring)."""
        for p, v in values.items():
            if p not in self.parameters():
                raise ValueError(
                    f"term '{self.name}' has no parameter '{p}'; it has {self.parameters()}"
                )
            self._check(p, v)
            setattr(self, p, float(v))
            for consts in self._live:
                consts.assign(p, float(v))

    def values(self) -> dict[str, float]:
        """The parameters as floats (usable as ``p`` of :meth:`density`: then compiled in)."""
        return {p: float(getattr(self, p)) for p in self.parameters()}

    def small_stretch_stiffness(self) -> float:
        """d²W/dλ² at λ = μ = 1 of a fibre term, the larger family's (N/mm): the fibres'
        stiffness against which a mesh may lock (docs/theory.md, "Locking"); 0 for the
        others. A quadratic term's is its largest modulus."""
        return max(self.values().values(), default=0.0) if self.fibre else 0.0

    def stiffness_scale(self, p: Params):
        """Scale S of the second-gradient moduli, used by the interior penalty (zero if order 1)."""
        return sum(p[q] for q in self.parameters()) if self.order == 2 else 0.0

    def density(self, kin: Kinematics, p: Params):
        """W per unit reference area (UFL), with ``p[name]`` the value of each parameter."""
        raise NotImplementedError

    def shear_moment(self, gamma, angles: tuple[float, float] = BIAS_ANGLES) -> np.ndarray:
        """τ(γ) = dW/dγ (N/mm) of this term alone in the pure shear of inextensible fibres at
        ``angles`` (deg) the three-zone kinematics of the bias test asks for (Cao et al. 2008
        eq. 18), derived from :meth:`density` (fabricsurf/model/pure_shear.py); 0 for a term
        that does not depend on the shear angle."""
        return pure_shear.shear_moment([self], gamma, angles)

    def constraints(self, kin: Kinematics, p: Params) -> list[tuple[str, object, object]]:
        """Exact constraints (name, g, r) with g(u) = 0 enforced by a multiplier and r the
        augmentation stiffness (discretise/constraints.py); none by default."""
        return []

    def tensions(self, kin: Kinematics, p: Params) -> dict:
        """Named fibre tensions (N/mm, UFL) the term's own energy carries; none by default."""
        return {}
