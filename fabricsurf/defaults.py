"""Physical defaults shared by the continuum model and the lattice reference.

The lowest layer beside :mod:`fabricsurf.errors`: every layer may import it, so that the
continuum terms and the spring networks agree on a default without importing each other.
"""

from __future__ import annotations

import math

FRICTION_ANGLE = math.radians(1.0)
"""Default shape angle γ_f (rad) of inter-yarn friction at the crossovers: the continuum
``crossover_friction`` term τ_f γ_f ln cosh(γ/γ_f) and the lattice's friction springs use the
same value, so lattice and continuum data match."""
