"""Energy-term vocabulary: exact names, validation, Constants updated without recompiling."""

import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.model.kinematics import Kinematics, fibre_directions
from fabricsurf.model.terms import (
    EFFECTS,
    FibreStretch,
    GeodesicBending,
    Shear,
    ShearLocking,
    make_term,
    parse_terms,
)

VOCABULARY = ["fibre_stretch", "shear", "shear_locking", "crossover_friction", "geodesic_bending",
              "stretch_gradient", "shear_gradient", "normal_bending", "twist", "yarn_slip"]


def test_vocabulary_is_exact():
    assert list(EFFECTS) == VOCABULARY


@pytest.mark.parametrize("bad", [-1.0, math.inf, math.nan, "abc"])
def test_bad_modulus_names_term_and_parameter(bad):
    with pytest.raises(ValueError, match=r"term 'shear': parameter k_s"):
        Shear(k_s=bad)
    t = GeodesicBending(A_g=1.0)
    with pytest.raises(ValueError, match=r"term 'geodesic_bending': parameter A_g"):
        t.set(A_g=bad)
    assert t.A_g == 1.0
    with pytest.raises(ValueError, match=r"term 'shear_locking': parameter k6"):
        ShearLocking(k4=1.0, k6=bad)


def test_unknown_term_lists_valid_names():
    with pytest.raises(ValueError, match=r"unknown term 'bending'.*fibre_stretch, shear"):
        parse_terms("fibre_stretch,bending")
    with pytest.raises(ValueError, match="has no parameter"):
        make_term("shear", k_l=1.0)


def test_parse_terms_with_params():
    model = parse_terms("fibre_stretch, shear", {"shear": {"k_s": 2.5}})
    assert [t.name for t in model] == ["fibre_stretch", "shear"]
    assert model[1].k_s == 2.5


def test_set_updates_the_constants_of_a_form_in_place():
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 1, 1)
    t = FibreStretch(k_l=3.0)
    consts = t.constants(msh)
    c = consts["k_l"]
    t.set(k_l=7.0)
    assert consts["k_l"] is c and float(c.value) == 7.0


def test_shear_locking_density_is_the_quartic_sextic_polynomial():
    """Simple shear r = (x + s y, y) of 0/90° fibres has γ = atan s: the density is
    ¼k₄γ⁴ + ⅙k₆γ⁶, and one compiled expression serves all moduli (its own constants)."""
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 1, 1)
    s = 0.8
    x = ufl.SpatialCoordinate(msh)
    r = ufl.as_vector((x[0] + s * x[1], x[1]))
    term = ShearLocking(k4=2.0, k6=3.0)
    consts = term.constants(msh)
    expr = fem.Expression(term.density(Kinematics(ufl.grad(r), None, *fibre_directions(0, 90)),
                                       consts),
                          np.array([[1 / 3, 1 / 3]]))
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    g = math.atan(s)
    for k4, k6 in [(2.0, 3.0), (0.0, 1.0), (5.0, 0.0)]:
        term.set(k4=k4, k6=k6)
        assert np.allclose(expr.eval(cells), k4 * g**4 / 4 + k6 * g**6 / 6, rtol=1e-14, atol=0)
