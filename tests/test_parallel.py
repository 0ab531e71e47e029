"""Rung 7: results agree between 1 and 2 ranks (docs/theory.md, §8).

Under ``mpirun -n 2`` the same bias-extension problem is solved on COMM_WORLD (distributed mesh)
and on COMM_SELF (the whole mesh on each rank); gmsh builds the identical mesh for both. The
reaction force, shear angles at A and B and the L2 norm of u agree to the Newton tolerance
(relative residual 1e-10), asserted at 1e-7. Run serially, the test checks the same on 1 rank.
"""

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.experiments.bias_extension import BiasExtension


def solve(comm):
    b = BiasExtension(h=16.0, comm=comm)
    res = b.run(20.0, 2, verbose=False)
    u = b.problem.u
    dx = ufl.Measure("dx", domain=u.function_space.mesh, metadata={"quadrature_degree": 4})
    norm = np.sqrt(comm.allreduce(fem.assemble_scalar(fem.form(ufl.inner(u, u) * dx))))
    return np.array(res.force + res.angle_A_deg + res.angle_B_deg + [norm])


def test_one_vs_all_ranks_agree():
    world = solve(MPI.COMM_WORLD)
    single = solve(MPI.COMM_SELF)
    print("world:", world, "\nself: ", single)
    assert np.all(np.isfinite(world))
    assert np.allclose(world, single, rtol=1e-7, atol=1e-9)
