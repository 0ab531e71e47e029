"""Every mesh the package builds carries shared-facet ghosts: the interior-penalty terms are
integrals over interior facets, and a facet on a partition boundary is interior only if the
cells on both of its sides are present on the rank that owns it. Without ghosts those facets
would count as exterior on both ranks and their penalty would silently vanish.

The check: the total length of the interior facets, assembled as ∫ 1 dS over the distributed
mesh, equals that of the same mesh on one process (every rank builds it whole). In the serial
session the two are the same mesh, so the test runs in the 2-rank session."""

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.geometry.aligned import fibre_aligned_rectangle
from fabricsurf.geometry.specimen import rectangle, structured_rectangle

BUILDERS = {
    "gmsh rectangle": lambda comm: rectangle(30.0, 15.0, 3.0, comm),
    "structured rectangle": lambda comm: structured_rectangle(30.0, 15.0, 10, 5, comm),
    "fibre-aligned rectangle": lambda comm: fibre_aligned_rectangle(30.0, 15.0, 3.0, 45.0, comm),
}


def interior_facet_length(msh) -> float:
    one = fem.form(ufl.avg(fem.Constant(msh, 1.0)) * ufl.dS(domain=msh))
    return msh.comm.allreduce(fem.assemble_scalar(one), op=MPI.SUM)


@pytest.mark.skipif(MPI.COMM_WORLD.size == 1, reason="a partition boundary needs 2 ranks")
@pytest.mark.parametrize("name", sorted(BUILDERS))
def test_interior_facets_on_partition_boundaries_are_kept(name):
    distributed = BUILDERS[name](MPI.COMM_WORLD).mesh
    whole = BUILDERS[name](MPI.COMM_SELF).mesh
    cells = distributed.topology.index_map(2)
    assert MPI.COMM_WORLD.allreduce(cells.size_local) == whole.topology.index_map(2).size_local
    assert MPI.COMM_WORLD.allreduce(cells.num_ghosts) > 0, "no ghost cells at all"
    assert np.isclose(interior_facet_length(distributed), interior_facet_length(whole), rtol=1e-12)
