"""The forming indicators of the hemisphere plug-in (experiments/hemisphere.py): where the sheet
wrinkles and where it is sheared beyond the locking angle.

Wrinkling: a fibre in compression, T < −T_w, that bends more sharply than κ_w, |K| > κ_w (K
its normal curvature K_L or K_M): compression relieved out of plane. Beyond locking: |γ| >
γ_lock. Both are 0/1 fields of the reference blank; their integrals give the area that
wrinkles and the area beyond locking.

The thresholds T_w, κ_w and γ_lock are ``fem.Constant``s: a form holding them is compiled once
for all values (before issue 40 they were plain numbers in the form, so that each new punch
radius, whose 1/R is the default κ_w, compiled the two forms again). What the indicator marks
is compared with the flange's out-of-plane amplitude and a buckling estimate in
fabricsurf/verification/wrinkling.py (docs/forming.md, "Wrinkling").
"""

from __future__ import annotations

import math

import ufl
from dolfinx import fem


class Indicators:
    """The wrinkling and beyond-locking indicators (module docstring), their thresholds
    ``fem.Constant``s on ``msh``: ``tension`` T_w (N/mm), ``curvature`` κ_w (1/mm),
    ``locking`` γ_lock (rad). Set a threshold's ``value`` to change it without recompiling."""

    def __init__(self, msh, tension: float, curvature: float, locking_deg: float) -> None:
        self.tension = fem.Constant(msh, float(tension))
        self.curvature = fem.Constant(msh, float(curvature))
        self.locking = fem.Constant(msh, math.radians(locking_deg))

    @classmethod
    def from_options(cls, msh, options: dict) -> Indicators:
        """From the plug-in's ``[tooling]`` options (forming_options.parse)."""
        return cls(msh, options["wrinkle_tension"], options["wrinkle_curvature"],
                   options["locking_angle_deg"])

    def wrinkle(self, kin, tensions: dict):
        """1 where a fibre is compressed beyond T_w and bends beyond κ_w, else 0 (UFL);
        ``tensions`` holds ``tension_l`` and ``tension_m`` (EnergyForm.tension_fields)."""
        flags = [ufl.conditional(ufl.And(ufl.lt(tensions[f"tension_{f}"], -self.tension),
                                         ufl.gt(abs(K), self.curvature)), 1.0, 0.0)
                 for f, K in (("l", kin.K_L), ("m", kin.K_M))]
        return ufl.max_value(*flags)

    def locked(self, kin):
        """1 where |γ| > γ_lock, else 0 (UFL)."""
        return ufl.conditional(ufl.gt(abs(kin.gamma), self.locking), 1.0, 0.0)
