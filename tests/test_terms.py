"""Energy-term vocabulary: exact names, validation, Constants updated without recompiling."""

import math

import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.model.terms import (
    EFFECTS,
    FibreStretch,
    GeodesicBending,
    Shear,
    make_term,
    parse_terms,
)

VOCABULARY = ["fibre_stretch", "shear", "geodesic_bending", "stretch_gradient",
              "shear_gradient", "normal_bending", "twist"]


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


def test_unknown_term_lists_valid_names():
    with pytest.raises(ValueError, match=r"unknown term 'bending'.*fibre_stretch, shear"):
        parse_terms("fibre_stretch,bending")
    with pytest.raises(ValueError, match="has no parameter"):
        make_term("shear", k_l=1.0)


def test_parse_terms_with_params():
    model = parse_terms("fibre_stretch, shear", {"shear": {"k_s": 2.5}})
    assert [t.name for t in model] == ["fibre_stretch", "shear"]
    assert model[1].k_s == 2.5


def test_set_updates_bound_constant_in_place():
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 1, 1)
    t = FibreStretch(k_l=3.0).bind(msh)
    c = t.p("k_l")
    t.set(k_l=7.0)
    assert t.p("k_l") is c and float(c.value) == 7.0
