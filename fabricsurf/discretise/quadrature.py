"""The quadrature of Π_h (discretise/energy.py): the degrees of its cell and facet integrals, and
how the fibre terms are integrated over a cell, fully or at one point (the reduced treatment
that keeps meshes whose edges do not follow the fibres from locking; docs/theory.md,
"Locking"). The plug-ins and the output fields read their values at the same points."""

from __future__ import annotations

import basix
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

CELL_QUADRATURE_DEGREE = 4
"""Quadrature degree of the cell integrals of Π_h (and of what is evaluated at its points)."""
FACET_QUADRATURE_DEGREE = 4
"""Quadrature degree of the facet integrals: the interior penalty and Nitsche terms."""
FIBRE_TREATMENTS = ("full", "reduced")
"""How the fibre terms (:attr:`Term.fibre`) are integrated over a cell: ``full`` at the
quadrature degree of every other term; ``reduced`` at one point, the centroid (an assumed
fibre strain constant per cell, the P2/P0 mixed form at the linear level; docs/theory.md,
"Locking"): the treatment that does not lock on meshes whose edges do not follow the fibres."""


REDUCED_FIBRE_DEGREE = 1
"""Quadrature degree of the fibre terms under the ``reduced`` treatment: one point per triangle."""
FIBRE_CELLS = 1
"""The subdomain id of the reduced fibre integrals (every cell; :func:`reduced_measures`)."""


def reduced_measures(msh, degree: int) -> tuple[ufl.Measure, ufl.Measure]:
    """(dx, dx_fibre): the cell measure at ``degree`` and that of the reduced fibre terms, at
    :data:`REDUCED_FIBRE_DEGREE`, over the same cells but under their own subdomain id.

    FFCx 0.5 merges the integrals of one subdomain into one kernel, and with two quadrature
    degrees in it the Jacobian it generates is wrong (2 % off the derivative of the residual
    at a random state, measured by finite differences); with its own subdomain id the fibre
    integral gets its own kernel. dolfinx integrates the unmarked ``dx`` over every cell."""
    tdim = msh.topology.dim
    imap = msh.topology.index_map(tdim)
    cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    tags = dmesh.meshtags(msh, tdim, cells, np.full(len(cells), FIBRE_CELLS, dtype=np.int32))
    dx = ufl.Measure("dx", domain=msh, subdomain_data=tags, metadata={"quadrature_degree": degree})
    return dx, dx(FIBRE_CELLS, metadata={"quadrature_degree": REDUCED_FIBRE_DEGREE})


def quadrature_points(msh) -> np.ndarray:
    """The reference points of the cell quadrature (degree CELL_QUADRATURE_DEGREE), in the
    order of the quadrature space's degrees of freedom on a cell: where the tools given as
    surfaces are tabulated (experiments/forming/tabulated_tools.py)."""
    cell = basix.cell.string_to_type(msh.topology.cell_name())
    return basix.make_quadrature(cell, CELL_QUADRATURE_DEGREE)[0]


def quadrature_table(msh, dim: int) -> tuple[fem.FunctionSpace, np.ndarray, np.ndarray]:
    """(the space of ``dim``-vectors at the cell quadrature points, the local and ghost cells,
    the degree of freedom of each of their points in cell order): where a numpy function of the
    placement is tabulated (experiments/forming/tabulated_tools.py, surfaces/holder.py)."""
    element = ufl.VectorElement(
        "Quadrature", msh.ufl_cell(), CELL_QUADRATURE_DEGREE, quad_scheme="default", dim=dim
    )
    Q = fem.FunctionSpace(msh, element)
    imap = msh.topology.index_map(msh.topology.dim)
    cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    dofs = Q.dofmap.list.array.reshape(-1, len(quadrature_points(msh)))[cells].ravel()
    return Q, cells, dofs
