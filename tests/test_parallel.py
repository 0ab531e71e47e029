"""Results agree between 1 and 2 ranks (docs/verification.md, "Parallel").

The same bias-extension problem (gmsh builds the identical mesh on any number of ranks) is
solved on a distributed mesh and on the whole mesh in one process: the reaction force, the
shear angles at A and B and the L2 norm of u agree to the Newton tolerance (relative residual
1e-10), asserted at 1e-7.

* Serial session: this file is run as a script under ``mpirun -n 2`` (a process of its own,
  started here), which writes its 2-rank result; the test compares it with the 1-rank solve.
* 2-rank session: COMM_WORLD (distributed) against COMM_SELF (the whole mesh on each rank).
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.experiments.bias_extension import BiasExtension

COMM = MPI.COMM_WORLD
ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_rmaps_base_oversubscribe": "1",
    "OMP_NUM_THREADS": "1",
}


def solve(comm) -> np.ndarray:
    """Force, angles at A and B per step, and ‖u‖_L2 at the end (reduced over ``comm``)."""
    b = BiasExtension(h=16.0, comm=comm)
    res = b.run(20.0, 2)
    u = b.problem.u
    dx = ufl.Measure("dx", domain=u.function_space.mesh, metadata={"quadrature_degree": 4})
    norm = np.sqrt(comm.allreduce(fem.assemble_scalar(fem.form(ufl.inner(u, u) * dx))))
    return np.array(res.force + res.angle_A_deg + res.angle_B_deg + [norm])


@pytest.mark.skipif(COMM.size > 1, reason="starts mpirun -n 2 itself (serial session only)")
def test_serial_matches_two_ranks(tmp_path):
    out = tmp_path / "two_ranks.json"
    p = subprocess.run(
        ["mpirun", "-n", "2", sys.executable, __file__, str(out)],
        env=dict(os.environ, **ENV),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    two = json.loads(out.read_text())
    assert two["ranks"] == 2
    one = solve(MPI.COMM_SELF)
    print("1 rank: ", one, "\n2 ranks:", np.array(two["result"]))
    assert np.all(np.isfinite(one))
    assert np.allclose(two["result"], one, rtol=1e-7, atol=1e-9)


@pytest.mark.skipif(COMM.size == 1, reason="needs 2 ranks; serially see the test above")
def test_distributed_matches_whole_mesh():
    world = solve(COMM)
    single = solve(MPI.COMM_SELF)
    print("world:", world, "\nself: ", single)
    assert np.all(np.isfinite(world))
    assert np.allclose(world, single, rtol=1e-7, atol=1e-9)


if __name__ == "__main__":
    result = solve(COMM)
    if COMM.rank == 0:
        Path(sys.argv[1]).write_text(json.dumps({"ranks": COMM.size, "result": result.tolist()}))
