"""The first-gradient forms of a model with second-gradient terms (discretise/solver.py
``add_cheap_forms``, docs/speed.md): while every second-gradient modulus is zero, the residual
and the Jacobian are assembled from the first-gradient terms alone. There they are the full
forms exactly: each second-gradient density, the double force M and the penalty factor S are
proportional to the moduli, so the cell kernels and the interior-penalty and Nitsche facet
terms they drop add zeros. Checked at a random state (not an equilibrium, so no term is small
by accident), to the round-off of the generated kernels; and a modulus above zero brings the
full forms back."""

import numpy as np
import pytest
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabricsurf.discretise.resources import destroy
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy

BASE = {"fibre_stretch": {"k_l": 25.0, "k_m": 25.0}, "shear": {"k_s": 0.4}}
CANDIDATES = ["geodesic_bending", "stretch_gradient", "shear_gradient", "shear_locking"]
"""Among the vocabulary's other effects, all in the model (a diagnosis's full model)."""


def assembled(s, pair):
    """(residual vector, Jacobian matrix) of the forms ``pair`` at the solver's u, no BCs."""
    b = fem_petsc.assemble_vector(pair[0])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    A = fem_petsc.assemble_matrix(pair[1])
    A.assemble()
    return b, A


@pytest.fixture(scope="module")
def model_at_zero():
    exp = sy.template(48.0, 24.0, [2.0], sy.grid_points(48.0, 24.0, 8, 4))
    model = full_model(list(BASE) + CANDIDATES, BASE)
    with ForwardModel(exp, model, h=4.0) as fm:
        fm.set_values([v if t.name in BASE else 0.0 for (t, _), v in zip(fm.params, fm.values())])
        fm.run()  # the candidates at modulus 0, as in a diagnosis's baseline
        s = fm.test.solver
        rng = np.random.default_rng(7 + MPI.COMM_WORLD.rank)
        s.u.x.array[:] += 0.05 * rng.standard_normal(s.u.x.array.size)
        s.u.x.scatter_forward()
        yield fm, s


def test_cheap_forms_are_the_full_forms_at_zero_moduli(model_at_zero):
    s = model_at_zero[1]
    used = s.cheap_evaluations
    cheap, full = s.forms(), (s.L, s.a)
    assert cheap[0] is not s.L and s.cheap_evaluations == used + 1
    (bc, Ac), (bf, Af) = assembled(s, cheap), assembled(s, full)
    try:
        db, dA = bc.copy(), Af.copy()
        db.axpy(-1.0, bf)
        dA.axpy(-1.0, Ac, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        print(db.norm() / bf.norm(), dA.norm() / Af.norm())
        assert db.norm() <= 1e-13 * bf.norm() and bf.norm() > 0
        assert dA.norm() <= 1e-13 * Af.norm() and Af.norm() > 0
        assert Ac.getInfo()["nz_used"] < Af.getInfo()["nz_used"]  # the facet couplings: absent
    finally:
        destroy(bc, Ac, bf, Af, db, dA)


def test_a_second_gradient_modulus_brings_the_full_forms_back(model_at_zero):
    fm, s = model_at_zero
    names = [f"{t.name}.{p}" for t, p in fm.params]
    vals = fm.values()
    try:
        vals[names.index("geodesic_bending.A_g")] = 1.0
        fm.set_values(vals)
        used = s.cheap_evaluations
        assert s.forms() == (s.L, s.a) and s.cheap_evaluations == used
        vals[names.index("geodesic_bending.A_g")] = 0.0
        vals[names.index("shear_locking.k4")] = 1.0  # first-gradient: still cheap
        fm.set_values(vals)
        assert s.forms()[0] is not s.L
    finally:
        fm.set_values(np.where(np.isin(names, ["shear_locking.k4"]), 0.0, vals))


def test_full_forms_after_cheap_ones_on_the_same_solver():
    """The first run that needs the full forms follows runs on the cheap ones. PETSc fixes an
    AIJ matrix's structure at its first assembly: when the cheap forms shared the full
    Jacobian's matrix and assembled it first, the distributed matrix had no room for the facet
    couplings, and every Newton solve of the next run with A_g > 0 failed. The cheap forms now
    factorise a matrix of their own, of fewer entries (half the factorisation time,
    docs/speed.md), and SNES is given the full one again when a second-gradient modulus is on.
    That run equals a fresh model's at the same moduli, with the sensitivities; on 2 ranks the
    mesh is distributed (``local=False``)."""
    exp = sy.template(48.0, 24.0, [1.0, 2.0], sy.grid_points(48.0, 24.0, 8, 4))

    def moduli(fm, A_g: float) -> list[float]:
        return [
            v if t.name in BASE else A_g if t.name == "geodesic_bending" else 0.0
            for (t, _), v in zip(fm.params, fm.values())
        ]

    runs = []
    for warm in (True, False):
        with ForwardModel(exp, full_model(list(BASE), BASE), h=4.0, local=False) as fm:
            s = fm.test.solver
            if warm:
                fm.set_values(moduli(fm, 0.0))
                fm.run()
                assert s.cheap_evaluations > 0 and s._in_use is s.A_cheap
                assert s.A_cheap.getInfo()["nz_allocated"] < 0.6 * s.A.getInfo()["nz_allocated"]
            fm.set_values(moduli(fm, 8.0))
            runs.append(fm.run(sens=True))
            assert s._in_use is s.A
    after, fresh = runs
    assert np.abs(fresh.force).max() > 0
    np.testing.assert_allclose(after.u, fresh.u, rtol=0, atol=1e-9 * np.abs(fresh.u).max())
    np.testing.assert_allclose(after.force, fresh.force, rtol=1e-9)
    np.testing.assert_allclose(after.du, fresh.du, rtol=0, atol=1e-7 * np.abs(fresh.du).max())
