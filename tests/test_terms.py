"""Energy-term vocabulary: exact names, validation, Constants updated without recompiling, what
a term knows about itself (which data can see it, its locking angle), and the model layer's
imports going one way."""

import ast
import math
from pathlib import Path

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
    in_plane_invisible,
    make_term,
    parse_terms,
)

VOCABULARY = [
    "fibre_stretch",
    "shear",
    "shear_locking",
    "crossover_friction",
    "geodesic_bending",
    "stretch_gradient",
    "shear_gradient",
    "normal_bending",
    "twist",
    "yarn_slip",
]


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
    expr = fem.Expression(
        term.density(Kinematics(ufl.grad(r), None, *fibre_directions(0, 90)), consts),
        np.array([[1 / 3, 1 / 3]]),
    )
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    g = math.atan(s)
    for k4, k6 in [(2.0, 3.0), (0.0, 1.0), (5.0, 0.0)]:
        term.set(k4=k4, k6=k6)
        assert np.allclose(expr.eval(cells), k4 * g**4 / 4 + k6 * g**6 / 6, rtol=1e-14, atol=0)


def test_which_data_can_see_a_term_is_a_property_of_the_term():
    """Out-of-plane bending and twist act on placements in 3D only (docs/vocabulary.md): their
    class says so (``in_plane`` False), every other effect's says planar data can see it, and
    the list the diagnosis and the command line read is derived from the registry."""
    assert in_plane_invisible() == ("normal_bending", "twist")
    assert [n for n, c in EFFECTS.items() if c.in_plane] == [
        n for n in VOCABULARY if n not in ("normal_bending", "twist")
    ]


def _model_imports(module: Path) -> set[str]:
    """The fabricsurf.model modules ``module`` imports when it runs (at any level of its
    source; those under ``if TYPE_CHECKING:`` are for type checkers only)."""
    names, tree = set(), ast.parse(module.read_text())
    skip = {
        id(n)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING"
        for n in ast.walk(node)
    }
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom) and node.module:
            names |= (
                {f"{node.module}.{a.name}" for a in node.names}
                if node.module == "fabricsurf.model"
                else {node.module}
            )
        elif isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
    return {n.rsplit(".", 1)[-1] for n in names if n.startswith("fabricsurf.model.")}


def test_model_modules_import_one_way():
    """No import circle in the model layer (terms.py imported slip.py, which imported terms.py
    back for the base class): the import graph of fabricsurf/model is acyclic."""
    folder = Path(__file__).resolve().parents[1] / "fabricsurf" / "model"
    graph = {p.stem: _model_imports(p) for p in folder.glob("*.py") if p.stem != "__init__"}
    done: set[str] = set()

    def visit(node: str, path: tuple[str, ...]) -> None:
        assert node not in path, f"import circle: {' -> '.join(path + (node,))}"
        if node not in done:
            for nxt in graph.get(node, ()):
                visit(nxt, path + (node,))
            done.add(node)

    for node in graph:
        visit(node, ())
    assert {"slip", "term"} <= graph["terms"] and "term" in graph["slip"]  # read at all


def test_locking_angle_is_where_the_locking_moment_equals_the_linear_one():
    """ShearLocking.locking_angle(k_s) is the γ at which the locking term's own shear moment
    (derived from its density) equals that of ``shear`` (to round-off), with k₄ and k₆, with
    k₄ alone (√(k_s/k₄)), and None without locking moduli."""
    k_s = 0.02
    for lock in (ShearLocking(k4=0.01, k6=0.005), ShearLocking(k4=0.03, k6=0.0)):
        g = lock.locking_angle(k_s)
        assert abs(lock.shear_moment(g) - Shear(k_s=k_s).shear_moment(g)) < 1e-15
    assert math.isclose(ShearLocking(k4=0.03, k6=0.0).locking_angle(k_s), math.sqrt(2 / 3))
    assert ShearLocking(k4=0.0, k6=0.0).locking_angle(k_s) is None
