"""The die's opening (opening.py) in UFL: σ and ∇σ as expressions of the placement r, for the
contact forms of experiments/forming/tools.py; the same formulas as the numpy ones."""

from __future__ import annotations

import ufl
from dolfinx import fem

from fabricsurf.experiments.forming.surfaces.opening import AXIS_EPS, CORNER_EPS, Opening


class OpeningForm:
    """σ and ∇σ of an :class:`Opening` as UFL expressions of the placement r, its sizes in
    fem.Constants (other sizes of the same kind use the same compiled forms)."""

    def __init__(self, msh, opening: Opening) -> None:
        self.kind = opening.kind
        self.opening = opening
        a, b, c = opening.half_length, opening.half_width, opening.corner
        self.core = [fem.Constant(msh, v) for v in (a - c, b - c)]
        self.corner = fem.Constant(msh, c)
        self.delta = fem.Constant(msh, CORNER_EPS * (a + b))

    def sigma(self, r):
        if self.kind == "circle":
            return self._rho(r) - self.corner
        q, _, out = self._parts(r)
        return out + ufl.min_value(ufl.max_value(q[0], q[1]), 0.0) - self.corner

    def gradient(self, r):
        """∇σ as a 2-vector (module docstring)."""
        if self.kind == "circle":
            rho = self._rho(r)
            return ufl.as_vector([r[0] / rho, r[1] / rho])
        q, m, out = self._parts(r)
        s = [ufl.conditional(ufl.lt(r[i], 0.0), -1.0, 1.0) for i in range(2)]
        outside = ufl.as_vector([s[0] * m[0] / out, s[1] * m[1] / out])
        inside = ufl.conditional(
            ufl.gt(q[0], q[1]), ufl.as_vector([s[0], 0.0]), ufl.as_vector([0.0, s[1]])
        )
        return ufl.conditional(ufl.gt(m[0] + m[1], 0.0), outside, inside)

    def _rho(self, r):
        return ufl.sqrt(r[0] ** 2 + r[1] ** 2 + AXIS_EPS * self.corner**2)

    def _parts(self, r):
        q = [abs(r[i]) - self.core[i] for i in range(2)]
        m = [ufl.max_value(qi, 0.0) for qi in q]
        return q, m, ufl.sqrt(m[0] ** 2 + m[1] ** 2 + self.delta**2)
