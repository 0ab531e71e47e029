"""Graded structured meshes (geometry.specimen.structured_rectangle with grading)."""

import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.geometry.specimen import EDGE_TAGS, graded, structured_rectangle

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
    import fabricsurf.geometry.specimen as spec

    def fail(*args):
        raise ValueError("synthetic gmsh failure")

    monkeypatch.setattr(spec, "_build_rectangle", fail)
    with pytest.raises(RuntimeError, match="rank 0: ValueError: synthetic gmsh failure"):
        spec.rectangle(2.0, 1.0, 0.5, COMM)


def test_aligned_sizes_near_the_one_asked():
    """187 × 119 mm is 11 : 7, so its ±45° corner-to-corner lattices have 14 k rows: fibre
    edges of 12.02, 6.01, 4.007 mm. Near h = 10 those are 6.01 (finer) and 12.02 (coarser)."""
    from fabricsurf.geometry.aligned import lattice_sizes

    finer, coarser = lattice_sizes(187.0, 119.0, 10.0, 45.0)
    assert finer == pytest.approx(math.hypot(187 / 44, 119 / 28), rel=1e-12)
    assert coarser == pytest.approx(math.hypot(187 / 22, 119 / 14), rel=1e-12)
    assert lattice_sizes(187.0, 119.0, 12.020815280171307, 45.0)[1] == pytest.approx(12.0208153)


def test_mesh_coarser_than_asked_is_announced():
    """bias --h 10 on 187 × 119: the aligned mesh has h = 12.02 mm; the notice (printed on
    rank 0 before computing) says so, why, and which h gives a mesh no coarser than asked.
    Within 5 % nothing is said."""
    from types import SimpleNamespace

    from fabricsurf.experiments.bias_extension import default_model
    from fabricsurf.experiments.bias_mesh import choose_fibre_treatment

    def notice(asked, used):
        sp = SimpleNamespace(kind="aligned", h=used, length=187.0, width=119.0, note="")
        return choose_fibre_treatment(
            "auto", sp, default_model(), asked, (45.0, -45.0), (45.0, -45.0)
        )["notice"]

    text = notice(10.0, 12.020815280171307)
    assert "h = 12.02 mm (asked 10)" in text and "+20 % from the 10 mm asked" in text
    assert "whole number of cells between fibre lines" in text
    assert "no coarser than asked: h = 6.01 mm" in text
    assert "coarser than asked" not in notice(8.0, 6.010407640085654)
    assert "-25 % from the 8 mm asked" in notice(8.0, 6.010407640085654)
    assert notice(12.0, 12.020815280171307) == ""
