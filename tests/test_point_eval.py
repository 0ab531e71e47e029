"""Point evaluation by precomputed basis values (discretise/evaluation.py, PointLocator): the same
values as dolfinx's Function.eval (to round-off) on 1 and 2 ranks, NaN outside the mesh, the
mean over the cells at a vertex for a cellwise field; Function.eval is not called again for a
Lagrange field on straight triangles (it tabulated the element at every call: the evaluation
stage of a 10⁶-point diagnosis)."""

import numpy as np
import pytest
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.discretise.evaluation import PointLocator


def field(V):
    f = fem.Function(V)
    if V.dofmap.index_map_bs == 2:
        f.interpolate(lambda x: np.stack([np.sin(x[0] / 30.0) * x[1], x[0] * x[1] / 100.0]))
    else:
        f.interpolate(lambda x: np.cos(x[0] / 20.0) + x[1])
    return f


@pytest.mark.parametrize("element", [("vector", "CG", 2), ("scalar", "DG", 1)])
def test_basis_values_equal_eval(element, monkeypatch):
    msh = dmesh.create_rectangle(MPI.COMM_WORLD, [[0.0, 0.0], [187.0, 119.0]], [8, 5])
    kind, family, degree = element
    V = (fem.VectorFunctionSpace if kind == "vector" else fem.FunctionSpace)(msh, (family, degree))
    f = field(V)
    x, y = np.meshgrid(np.linspace(0.0, 187.0, 41), np.linspace(0.0, 119.0, 23))
    pts = np.vstack([np.column_stack([x.ravel(), y.ravel()]), [[200.0, 50.0]]])
    reference = PointLocator(msh, pts)
    reference._tables[id(V)] = (V, None)  # the former path: Function.eval
    expected = reference(f)
    at = PointLocator(msh, pts)
    calls = []
    eval_ = fem.Function.eval
    monkeypatch.setattr(fem.Function, "eval", lambda self, *a: calls.append(1) or eval_(self, *a))
    got = at(f)
    assert not calls
    assert np.isnan(got[-1]).all() and np.isfinite(got[:-1]).all()
    assert np.allclose(got[:-1], expected[:-1], rtol=0.0, atol=1e-12 * np.abs(expected[:-1]).max())
    same = MPI.COMM_WORLD.allgather(got[:-1])
    assert all(np.array_equal(g, same[0]) for g in same)
