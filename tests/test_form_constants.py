"""Forms own their constants (issue 42, item 4): one model on two meshes, two models at once.

Every fem.Constant and every coefficient of a form built by an EnergyForm lives on that form's
mesh, whatever was built since on other meshes; its value equals a fresh build on that mesh
alone; ``Term.set`` changes every live form built from the term. Before, a term held the
constants of the mesh bound last and the forms were built lazily from them: the energy of mesh
A asked for after an energy on mesh B carried B's constants (for the bi-pantographic bending
term, B's DG0 penalty field).

Runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``.
"""

import numpy as np
import pytest
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.discretise.energy import EnergyForm
from fabricsurf.discretise.jit_keys import mark_equispaced
from fabricsurf.model.kinematics import fibre_directions
from fabricsurf.model.materials import bipantographic
from fabricsurf.model.terms import FibreStretch, GeodesicBending, Shear

COMM = MPI.COMM_WORLD


def woven():
    return [FibreStretch(k_l=30.0, k_m=20.0), Shear(k_s=0.5), GeodesicBending(A_g=40.0)]


def energy_on(msh, model) -> EnergyForm:
    """The energy of ``model`` on ``msh`` at a smooth placement whose P2 interpolant has
    gradient jumps (so the interior penalty, and with it the DG0 field of the bi-pantographic
    penalty stretch, contributes) and whose stretches stay inside the bi-pantographic domain."""
    V = fem.VectorFunctionSpace(msh, ("CG", 2), dim=2)
    u = fem.Function(V)
    u.interpolate(
        lambda x: np.vstack(
            [0.03 * np.sin(3 * x[0]) * np.cos(2 * x[1]), 0.03 * np.cos(2 * x[0]) * np.sin(x[1])]
        )
    )
    L, M = fibre_directions(45.0, -45.0, msh=msh)
    return EnergyForm(model, u, L, M)


def value(form) -> float:
    return COMM.allreduce(fem.assemble_scalar(form), op=MPI.SUM)


def fresh(msh, make, values) -> float:
    """Π_h (without loads) of a new model with ``values`` built on ``msh`` alone."""
    model = make()
    for t, v in zip(model, values):
        t.set(**v)
    return value(fem.form(energy_on(msh, model).internal()))


def foreign(form, msh) -> list[str]:
    """The constants and coefficients of a UFL form that do not live on ``msh``."""
    domain = msh.ufl_domain()
    return [str(c) for c in (*form.constants(), *form.coefficients()) if c.ufl_domain() != domain]


def test_forms_own_their_constants():
    mesh_a = mark_equispaced(dmesh.create_unit_square(COMM, 4, 4))
    mesh_b = mark_equispaced(dmesh.create_unit_square(COMM, 3, 5))
    makes = {"bipantographic": bipantographic, "woven": woven}
    models = {k: make() for k, make in makes.items()}
    energies = {
        (m, k): energy_on(m, model) for m in (mesh_a, mesh_b) for k, model in models.items()
    }  # mesh B built last
    forms = {}
    for (m, k), e in energies.items():
        for part in ("cell_energy", "internal"):
            assert not foreign(getattr(e, part)(), m), (k, part)
        forms[m, k] = fem.form(e.internal())
    for m in (mesh_a, mesh_b):
        for k in makes:
            defaults = [t.values() for t in makes[k]()]
            assert value(forms[m, k]) == pytest.approx(fresh(m, makes[k], defaults), rel=1e-13)

    pivot, bending = models["bipantographic"]
    before = {key: value(f) for key, f in forms.items()}
    pivot.set(K_S=0.05)
    bending.set(K_E=300.0, penalty_stretch=1.05)
    models["woven"][2].set(A_g=25.0)
    for m in (mesh_a, mesh_b):
        for k in makes:
            values = [t.values() for t in models[k]]
            got = value(forms[m, k])
            assert got != pytest.approx(before[m, k], rel=1e-6)
            assert got == pytest.approx(fresh(m, makes[k], values), rel=1e-13)
