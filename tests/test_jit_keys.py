"""Form cache keys do not depend on what was compiled or created before (the workarounds are
in fabricsurf.discretise.jit_keys).

* FFCx 0.5 marks an unmarked P1 coordinate element as equispaced, in place, while it analyses
  the first form it compiles on a mesh (ffcx.analysis), and the mark enters the key (UFL
  signature) of every later form on that mesh. Our meshes carry the mark from the start
  (geometry.specimen.coordinate_domain, Problem's mark_equispaced), so a form's key is the same
  whether earlier forms were compiled or read from the cache, and on every rank.
* UFL 2022 orders a sum of two Constants by their repr, in which the Constant's global count is
  text, so the key changes when the counts straddle a power of ten. Problem and EnergyForm
  number Constants from 10^6 on, so the key of a problem's residual does not depend on how many
  Constants the process made before it.

The ``compile`` option of SNESSolver ("fast": -O0) compiles the same forms under another key
and gives the same numbers; an unknown value is an error.
"""

import ffcx.analysis
import ffcx.parameters
import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import jit as djit
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.discretise.energy import EnergyForm
from fabricsurf.discretise.jit_keys import JIT_WAIT, mark_equispaced
from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.discretise.solver import SNESSolver
from fabricsurf.geometry.specimen import square
from fabricsurf.model.terms import FibreStretch, GeodesicBending, ShearGradient, StretchGradient

COMM = MPI.COMM_WORLD


def _key_before_and_after_analysis(msh) -> tuple[str, str]:
    """The signature of a form on ``msh`` before and after FFCx analyses another form there."""
    V = fem.VectorFunctionSpace(msh, ("CG", 2), dim=3)
    u = fem.Function(V)

    def form():
        return ufl.inner(ufl.grad(u), ufl.grad(u)) * ufl.dx

    before = form().signature()
    ffcx.analysis.analyze_ufl_objects([ufl.inner(u, u) * ufl.dx], ffcx.parameters.get_parameters())
    return before, form().signature()


def test_unmarked_mesh_changes_keys():
    """The FFCx behaviour the marking guards against: without it the key changes."""
    before, after = _key_before_and_after_analysis(dmesh.create_unit_square(COMM, 2, 2))
    assert before != after


def test_marked_meshes_keep_keys():
    """A gmsh-built specimen and a dolfinx mesh marked as Problem marks it keep their keys."""
    for msh in (square(1.0, 0.5, COMM).mesh, mark_equispaced(dmesh.create_unit_square(COMM, 2, 2))):
        before, after = _key_before_and_after_analysis(msh)
        assert before == after


def _sum_key(count: int) -> str:
    """The key of a form with a sum of two Constants numbered ``count`` and ``count + 1``."""
    msh = square(1.0, 0.5, COMM).mesh
    a, b = (ufl.Constant(msh.ufl_domain(), count=count + k) for k in (0, 1))
    x = ufl.SpatialCoordinate(msh)
    return (((a + b) * x[0] + a * x[1]) * ufl.dx).signature()


def test_constant_counts_across_a_power_of_ten_change_keys():
    """The UFL behaviour the numbering guards against: 9 and 10 sort as "10" < "9"."""
    assert _sum_key(8) == _sum_key(10) != _sum_key(9)


def _residual_key(count: int) -> str:
    """The key of a residual whose second-gradient moduli are summed (the penalty scale), built
    after the process has made ``count`` Constants (the global counter is restored after)."""
    saved = ufl.Constant._globalcount
    ufl.Constant._globalcount = count
    try:
        model = [
            FibreStretch(k_l=10.0, k_m=10.0),
            ShearGradient(A_Gamma=1.0),
            GeodesicBending(A_g=0.5),
            StretchGradient(A_s=0.5),
        ]
        p = FabricProblem(square(1.0, 0.5, COMM), model)
        e = EnergyForm(p.model, p.u, p.L, p.M, p.specimen.facet_tags)
        return e.residual(ufl.TestFunction(p.V)).signature()
    finally:
        ufl.Constant._globalcount = max(saved, ufl.Constant._globalcount)


def test_problem_keys_do_not_depend_on_constants_made_before():
    """A fresh process (5 Constants made), one after 995 and one after 12 345 build the same
    residual under one key."""
    assert _residual_key(5) == _residual_key(995) == _residual_key(12345)


def _solver(compile_mode: str) -> tuple[SNESSolver, fem.Function]:
    """A nonlinear residual R = (u³ − 1 − x) v on P2 (Newton to u = (1 + x)^(1/3))."""
    msh = square(1.0, 0.5, COMM).mesh
    V = fem.FunctionSpace(msh, ("CG", 2))
    u, v, du = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    u.x.array[:] = 1.0
    x = ufl.SpatialCoordinate(msh)
    R = (u**3 - 1 - x[0]) * v * ufl.dx
    return SNESSolver(R, ufl.derivative(R, u, du), u, options={"compile": compile_mode}), u


def test_fast_compile_gives_the_same_numbers():
    results = []
    for mode in ("optimised", "fast"):
        s, u = _solver(mode)
        assert s.solve()[0] > 0
        results.append(u.x.array.copy())
        s.close()
    assert np.allclose(results[0], results[1], rtol=1e-12, atol=1e-14)
    with pytest.raises(ValueError, match="compile = 'quick'"):
        _solver("quick")


def test_a_problem_waits_for_kernels_other_processes_compile():
    """Two jobs on one cold cache: the second waits for the kernel the first compiles. The
    second-gradient kernels take minutes to compile, dolfinx's stock wait is 10 s; once a
    problem is built, every later form waits JIT_WAIT unless its own jit_params say otherwise."""
    FabricProblem(square(1.0, 0.5, COMM), [FibreStretch()])
    assert JIT_WAIT >= 600
    assert djit.get_parameters()["timeout"] >= JIT_WAIT
    assert djit.get_parameters({"timeout": 5})["timeout"] == 5
