"""Spring-network reference of Barchiesi et al. 2020 §3: engine, Hencky fabric lattice,
bi-pantographic lattice.

See ``docs/network.md`` for the micro-macro identification and the reconstruction notes, and
``docs/vocabulary.md`` for the identification with skew fibre cells and shear-locking springs.
"""

from fabricsurf.network.engine import SpringNetwork
from fabricsurf.network.equilibrium import (
    ConvergenceError,
    Dirichlet,
    newton,
    reaction,
    solve_steps,
)
from fabricsurf.network.hencky import Lattice, hencky_lattice, spanning_spacing
from fabricsurf.network.hencky_moduli import continuum_from_lattice, lattice_from_continuum

__all__ = [
    "ConvergenceError",
    "Dirichlet",
    "Lattice",
    "SpringNetwork",
    "continuum_from_lattice",
    "hencky_lattice",
    "lattice_from_continuum",
    "newton",
    "reaction",
    "solve_steps",
    "spanning_spacing",
]
