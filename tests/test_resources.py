"""Resource hygiene (fabricsurf/discretise/resources.py): every PETSc object the solver makes is
destroyed when its owner closes (a destroyed petsc4py object has handle 0), by ``close()``, by
``with`` and, when the owner goes by reference counting, by ``__del__``; the internal force is
assembled into one work vector, never a new one; an owner holds no reference cycle, so it goes
at the same point on every rank."""

import gc
import weakref

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.discretise.solver import SNESSolver
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.forward.runs import ForwardModel, ForwardSet
from fabricsurf.inverse.synthetic import generate as sy

BASE = {"fibre_stretch": {"k_l": 30.0, "k_m": 30.0}, "shear": {"k_s": 0.5}}


def quadratic_solver():
    """R = (u − 1) v per cell (DG0): one Newton step to u = 1."""
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    V = fem.FunctionSpace(msh, ("DG", 0))
    u, v, du = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    return SNESSolver((u - 1) * v * ufl.dx, du * v * ufl.dx, u), u


def petsc_objects(solver):
    return [solver.snes, solver.A, solver.b, solver.x, solver.force]


def destroyed(objs) -> bool:
    """True on every rank when every object is destroyed on every rank."""
    return MPI.COMM_WORLD.allreduce(all(o.handle == 0 for o in objs), op=MPI.LAND)


def test_solver_close_destroys_and_internal_force_reuses_its_vector():
    s, u = quadratic_solver()
    assert s.solve()[0] > 0 and np.allclose(u.x.array, 1.0)
    first = s.internal_force()
    handle = first.handle
    for _ in range(3):
        again = s.internal_force()
        assert again is first and again.handle == handle
    objs = petsc_objects(s)
    assert all(o.handle != 0 for o in objs)
    s.close()
    assert destroyed(objs)
    s.close()  # a second close does nothing


def test_context_manager_and_del_destroy():
    with quadratic_solver()[0] as s:
        objs = petsc_objects(s)
    assert destroyed(objs)
    gc.disable()  # the solver must go by reference counting alone (no cycle through SNES)
    try:
        s, _ = quadratic_solver()
        objs, ref = petsc_objects(s), weakref.ref(s)
        del s
        assert ref() is None
        # the __del__ fallback destroys in serial only: in parallel destroying is collective and
        # an owner may go on one rank alone (an error unwinding there), so close() does it
        assert destroyed(objs) == (MPI.COMM_WORLD.size == 1)
    finally:
        gc.enable()


def small_experiment():
    return sy.template(40.0, 20.0, [0.8, 1.6], sy.grid_points(40.0, 20.0, 4, 2))


def test_forward_model_closes_its_plugin_and_scout():
    fm = ForwardModel(small_experiment(), full_model(list(BASE), BASE), h=10.0)
    pred = fm.run(sens=[0])
    assert np.isfinite(pred.u).all() and np.isfinite(pred.dforce).all()
    solvers = [fm.test.solver, fm.coarse().test.solver]
    u = fm.test.problem.u
    fm.close()
    assert destroyed([o for s in solvers for o in petsc_objects(s)])
    assert u._petsc_x is None


def test_forward_set_goes_by_reference_counting_and_destroys():
    gc.disable()
    try:
        fs = ForwardSet([small_experiment()], full_model(list(BASE), BASE), h=10.0)
        fs.run()
        objs, ref = petsc_objects(fs.models[0].test.solver), weakref.ref(fs)
        serial = fs.models[0].solve_comm.size == 1  # a rank-local mesh's too (local.py)
        del fs
        assert ref() is None
        assert destroyed(objs) == serial  # as above
    finally:
        gc.enable()
    with ForwardSet([small_experiment()], full_model(list(BASE), BASE), h=10.0) as fs:
        objs = petsc_objects(fs.models[0].test.solver)
    assert destroyed(objs)
