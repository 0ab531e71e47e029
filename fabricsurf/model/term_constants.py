"""The parameters of one term on one mesh, owned by the form that made them.

A term (fabricsurf/model/terms.py) holds its moduli as floats. Every form built from it asks the
term for UFL objects of its own on its own mesh (:meth:`Term.constants`): ``fem.Constant``\\ s, or
a cellwise field where a parameter may vary from cell to cell (the bi-pantographic penalty
stretch). The term keeps weak references to them, so :meth:`Term.set` reaches every live form
built from that term object without recompiling, a form that is dropped is freed with its
constants, and no form depends on which mesh another form was built on. The references are not
part of the term's state: a copy or a pickle of it has no live forms (a test builds its forms
from its own copies, docs/usage.md, "Changing moduli").
"""

from __future__ import annotations

from collections.abc import Mapping

from dolfinx import fem


class TermConstants:
    """``c[name]``: the UFL object (fem.Constant or fem.Function) of one parameter of one term,
    on the mesh of the form that owns it; :meth:`assign` writes a value into it. The owner keeps
    the object (``EnergyForm.bound``): :meth:`Term.set` reaches it only while it lives."""

    def __init__(self, values: dict[str, fem.Constant | fem.Function]) -> None:
        self._values = values

    def __getitem__(self, name: str) -> fem.Constant | fem.Function:
        return self._values[name]

    def assign(self, name: str, value: float) -> None:
        """Set parameter ``name`` to ``value`` (a field: in every cell, ghosts included)."""
        target = self._values[name]
        if isinstance(target, fem.Function):
            target.x.array[:] = value
        else:
            target.value = value


Params = TermConstants | Mapping[str, float]
"""The ``p`` of ``Term.density``: a form's constants, or the floats of ``Term.values()``."""
