"""Graded structured meshes (geometry.specimen.structured_rectangle with grading)."""

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from geometry.specimen import EDGE_TAGS, graded, structured_rectangle

COMM = MPI.COMM_WORLD


def _integrate(form) -> float:
    return COMM.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM)


def test_graded_map_spacing():
    """The map fixes 0, 1/2, 1 and has slope 1 − g at the ends, 1 + g in the middle."""
    g = 0.6
    assert np.allclose(graded(np.array([0.0, 0.5, 1.0]), g), [0.0, 0.5, 1.0])
    d = 1e-6
    assert (graded(np.array([d]), g)[0] / d) == pytest.approx(1 - g, rel=1e-6)
    mid = (graded(np.array([0.5 + d]), g)[0] - 0.5) / d
    assert mid == pytest.approx(1 + g, rel=1e-6)


def test_graded_rectangle_area_edges_and_nesting():
    """Area and edge lengths of the rectangle are kept, every edge tag is present, and the
    vertices of level n are vertices of level 2n (nested study)."""
    L, W = 187.0, 119.0
    coarse = structured_rectangle(L, W, 11, 7, COMM, grading=0.6)
    fine = structured_rectangle(L, W, 22, 14, COMM, grading=0.6)
    msh = fine.mesh
    assert _integrate(fem.Constant(msh, 1.0) * ufl.dx) == pytest.approx(L * W, rel=1e-12)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=fine.facet_tags)
    for name, length in (("clamp", W), ("grip", W), ("bottom", L), ("top", L)):
        got = _integrate(fem.Constant(msh, 1.0) * ds(EDGE_TAGS[name]))
        assert got == pytest.approx(length, rel=1e-12), name
    xc = np.vstack(COMM.allgather(coarse.mesh.geometry.x[:, :2]))
    xf = np.vstack(COMM.allgather(msh.geometry.x[:, :2]))
    dist = np.min(np.linalg.norm(xc[:, None, :] - xf[None, :, :], axis=2), axis=1)
    assert dist.max() < 1e-9
    edge_h = np.min(np.diff(np.unique(np.round(xf[:, 0], 9))))
    assert edge_h == pytest.approx(L / 44 * (1 - 0.6), rel=0.05)


def test_grading_rejected():
    with pytest.raises(ValueError, match="grading"):
        structured_rectangle(1.0, 1.0, 2, 2, COMM, grading=1.0)


def test_gmsh_failure_on_rank0_raises_everywhere(monkeypatch):
    """A gmsh error on rank 0 is broadcast: every rank raises instead of waiting in
    the mesh distribution (on 2 ranks this test would hang without it)."""
    import geometry.specimen as spec

    def fail(*args):
        raise ValueError("synthetic gmsh failure")

    monkeypatch.setattr(spec, "_build_rectangle", fail)
    with pytest.raises(RuntimeError, match="rank 0: ValueError: synthetic gmsh failure"):
        spec.rectangle(2.0, 1.0, 0.5, COMM)
