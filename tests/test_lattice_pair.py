"""No locking on rectangles without a corner-to-corner fibre lattice, and never a silent
fallback (docs/theory.md, "Locking"; geometry/lattice_pair.py, experiments/bias_mesh.py).

The bias test (fibres ±45°, position clamps, fibre_stretch K + shear k_s = 0.022 N/mm) on
specimens whose sides admit no corner-to-corner lattice at h = W/10: before, the plug-in fell
back to gmsh's mesh without a word and the force was 3.6, 224 and 2·10⁵ times the three-zone
force at K = 10⁴, 10⁶, 10⁹ N/mm (250 × 115 mm, issue 37). The whole table over twelve sizes is
benchmarks/locking.py; here one size per mesh kind, the cheap runs, on 1 and 2 ranks.
"""

import itertools
import logging
import math

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI
from test_locking import tangent_zero_eigenvalues

from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.experiments.bias_mesh import check_bias_angles, specimen_mesh
from fabricsurf.experiments.three_zone import kinematic_force
from fabricsurf.geometry.aligned import canonical_angles, lattice_divisions, symmetric_angle
from fabricsurf.geometry.lattice_pair import pair_divisions, pair_triangles
from fabricsurf.log import PROGRESS
from fabricsurf.model.terms import FibreStretch, Shear

K_S = 0.022


def bias(length, width, ratio, **kw):
    return BiasExtension(
        [FibreStretch(k_l=ratio * K_S, k_m=ratio * K_S), Shear(k_s=K_S)],
        length=length,
        width=width,
        h=width / 10,
        clamp="position",
        **kw,
    )


def force_ratio(b, steps=3) -> float:
    L, W = b.specimen.length, b.specimen.width
    res = b.run(0.13 * L, steps)
    return res.force[-1] / float(
        kinematic_force(np.array(res.ubar[-1:]), L, W, [Shear(k_s=K_S)])[0]
    )


@pytest.mark.parametrize("length, width", [(250.0, 115.0), (320.0, 100.0)])
def test_lattice_pair_tiles_the_rectangle_with_fibre_edges(length, width):
    """No corner-to-corner lattice fits at W/10, and the pair of lattices tiles the rectangle
    exactly (areas sum to L·W, no sliver); all edges outside the band are along ±45°, x or y."""
    with pytest.raises(ValueError):
        lattice_divisions(length, width, width / 10, 45.0)
    P, Q, B = pair_divisions(length, width, width / 10, 45.0)
    assert P >= Q  # the band lies in the centre zone
    x, cells = pair_triangles(P, Q, B, width / Q, width / Q, length)
    e = x[cells[:, [1, 2, 0]]] - x[cells]
    area = 0.5 * np.abs(np.cross(e[:, 0], -e[:, 2]))
    assert math.isclose(area.sum(), length * width, rel_tol=1e-12)
    assert area.min() > 0.25 * (width / Q) ** 2
    xc = x[cells][:, :, 0]
    outside = np.all(xc <= P * width / Q + 1e-9, axis=1) | np.all(
        xc >= length - P * width / Q - 1e-9, axis=1
    )
    assert np.count_nonzero(~outside) == 2 * B * Q // 2  # the band: B columns of Q/2 cells
    ang = np.degrees(np.arctan2(e[outside][..., 1], e[outside][..., 0])) % 90.0
    assert np.all(
        np.isclose(ang, 0.0, atol=1e-9)
        | np.isclose(ang, 45.0, atol=1e-9)
        | np.isclose(ang, 90.0, atol=1e-9)
    )


def test_bias_force_without_locking_off_the_corner_lattice():
    """The force rises with K/k_s from 10² to 10⁹, never exceeds the three-zone force, and is
    within 2 % of it for nearly inextensible yarns (K/k_s ≥ 10⁶; the table over twelve sizes
    in benchmarks/locking.py). Today's fallback gave 6.7 and 5337 times it on 250 × 115 at
    K/k_s = 10⁶ and 10⁹."""
    length, width, ratios = 250.0, 115.0, (1e2, 1e6, 1e9)
    q = [force_ratio(bias(length, width, r)) for r in ratios]
    print(f"{length} x {width}: K/k_s {ratios}: force / three-zone {q}")
    assert all(a < b + 1e-4 for a, b in itertools.pairwise(q))
    assert q[-1] < 1.0 + 1e-4
    assert all(abs(v - 1.0) < 0.02 for r, v in zip(ratios, q) if r >= 1e6)
    assert q[0] < q[1] - 0.05  # soft fibres do stretch: the test can tell K apart


def test_fibre_pair_spellings_are_one_pair(caplog):
    """[45, 135] and [405, −45] are the fibres of [45, −45] (directions mod 180°): the same
    aligned mesh, the same force and shear angles (before: the gmsh mesh and 2.45× the force),
    and the run says it respelled them and records both spellings."""
    assert canonical_angles((45.0, 135.0)) == canonical_angles((405.0, -45.0)) == (45.0, -45.0)
    assert symmetric_angle((45.0, 135.0)) == symmetric_angle((-135.0, 135.0)) == 45.0
    assert specimen_mesh(230.0, 115.0, 11.5, (405.0, -45.0)).kind == "aligned"
    caplog.set_level(PROGRESS, logger="fabricsurf")
    res = {}
    for angles in [(45.0, -45.0), (45.0, 135.0)]:
        b = BiasExtension(
            [FibreStretch(k_l=1e6 * K_S, k_m=1e6 * K_S), Shear(k_s=K_S)],
            length=230.0,
            width=115.0,
            h=11.5,
            clamp="position",
            fibre_angles=angles,
        )
        assert b.discretisation["mesh_kind"] == "aligned"
        r = b.run(10.0, 1)
        res[angles] = (r.force[-1], r.angle_A_deg[-1], r.discretisation)
    out = caplog.text
    ref = res[(45.0, -45.0)]
    for angles in [(45.0, 135.0)]:
        assert np.allclose(res[angles][:2], ref[:2], rtol=1e-9, atol=1e-12)
        assert res[angles][2]["fibre_angles_given"] == list(angles)
        assert res[angles][2]["fibre_angles_used"] == [45.0, -45.0]
        if MPI.COMM_WORLD.rank == 0:
            assert f"fibre angles {list(angles)} deg are the fibre lines [45.0, -45.0]" in out


FAMILY = (
    (250, 115),
    (320, 100),
    (350, 120),
    (245, 110),
    (270, 95),
    (300, 130),
    (215, 70),
    (380, 110),
    (290, 85),
    (260, 75),
    (400, 105),
    (230, 103),
)
"""benchmarks/locking.py's twelve sizes: aspect 2.2 to 3.8, no corner-to-corner lattice at
W/10."""


@pytest.mark.parametrize("length, width", FAMILY)
def test_family_without_a_corner_lattice_is_within_2_percent(length, width):
    """Every size of the family on the default mesh at h = W/10: the force within 2 % of the
    three-zone limit at K/k_s = 10⁴ and 10⁹, never above it, and not falling as K grows
    (measured 0.982–0.988 and 0.993–1.0000). Below 10⁴ the fibres do stretch and the
    converged force itself is below the limit (at K/k_s = 10² on 250 × 115: 0.7068, 0.7028,
    0.7018 at W/10, W/20, W/40), so the limit is not the reference there."""
    q = [force_ratio(bias(length, width, r)) for r in (1e4, 1e9)]
    assert q[0] <= q[1] + 1e-6 and q[1] < 1.0 + 1e-6
    assert all(abs(v - 1.0) < 0.02 for v in q), q


def test_fallback_and_lattice_pair_are_announced_and_recorded(caplog):
    """Before anything is computed the run names the mesh kind, the h used, K/k_s and the
    fibre treatment (a note at PROGRESS); on a mesh that may lock (gmsh's, stiff fibres) a
    warning, which --quiet keeps, says LOCKED and the remedy; the result records the same."""
    caplog.set_level(PROGRESS, logger="fabricsurf")
    b = bias(250.0, 115.0, 1e6, mesh="unstructured")
    d = b.discretisation
    assert d["mesh_kind"] == "unstructured" and d["may_lock"] and d["h_used"] == 11.5
    assert d["fibre_treatment"] == "full" and d["fibre_stiffness_ratio"] == pytest.approx(1e6)
    pair = bias(250.0, 115.0, 1e6)
    assert pair.discretisation["mesh_kind"] == "lattice_pair"
    assert not pair.discretisation["may_lock"]
    assert math.isclose(pair.discretisation["h_used"], math.hypot(115 / 14, 115 / 14))
    soft = bias(250.0, 115.0, 10.0, mesh="unstructured")
    assert not soft.discretisation["may_lock"]
    said = {r.levelno: [] for r in caplog.records}
    for r in caplog.records:
        said[r.levelno].append(r.getMessage())
    if MPI.COMM_WORLD.rank > 0:
        assert not said
        return
    warned = "\n".join(said[logging.WARNING])
    assert len(said[logging.WARNING]) == 1
    assert warned.startswith("mesh: unstructured (mesh = 'unstructured' requested)")
    assert "K/k_s = 1e+06" in warned and "LOCKED" in warned and "Remedy" in warned
    assert any(
        m.startswith("note: mesh: lattice_pair (two fibre lattices of 14 × 14 steps")
        for m in said[PROGRESS]
    )


@pytest.mark.parametrize(
    "angles, match",
    [
        ((0.0, 90.0), "run from clamp to grip"),
        ((20.0, -20.0), "run from clamp to grip"),
        ((45.0, 47.0), "2 deg apart"),
        ((45.0, -135.0), "0 deg apart"),
    ],
)
def test_degenerate_fibre_pairs_are_refused_before_computing(angles, match):
    """Fibres near 0° (some run from clamp to grip: a tensile test) or nearly parallel as
    lines: a clear error naming the value, before any mesh is built."""
    with pytest.raises(ValueError, match=match):
        check_bias_angles(canonical_angles(angles), 230.0, 115.0)
    with pytest.raises(ValueError, match=match):
        BiasExtension(length=230.0, width=115.0, h=11.5, fibre_angles=angles)


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="dense eigenvalues of the whole tangent")
@pytest.mark.parametrize(
    "mesh, length, width, h",
    [
        ("lattice_pair", 60.0, 20.0, 5.0),
        ("lattice_pair", 47.0, 17.0, 4.0),
        ("zones", 40.0, 25.0, 5.0),
    ],
)
def test_tangent_null_space_on_the_new_meshes_is_the_continuum_one(mesh, length, width, h):
    """No spurious zero-energy modes on the lattice pair and the corner-line mesh: at the
    reference state the tangent (K/k_s = 10⁶) has exactly the 3 rigid motions of the plane
    without clamps, none with."""
    b = BiasExtension(
        [FibreStretch(k_l=1e6 * K_S, k_m=1e6 * K_S), Shear(k_s=K_S)],
        length=length,
        width=width,
        h=h,
        clamp="position",
        mesh=mesh,
        comm=MPI.COMM_SELF,
    )
    assert b.discretisation["mesh_kind"] == mesh
    assert tangent_zero_eigenvalues(b, with_bcs=False) == 3
    assert tangent_zero_eigenvalues(b, with_bcs=True) == 0


def test_degenerate_fibre_pair_in_the_data_is_refused_by_key():
    """Through the measurement contract: a DataError naming the file, the key and the value."""
    from fabricsurf.errors import DataError
    from fabricsurf.experiments.base import PluginSetup
    from fabricsurf.experiments.bias_plugin import BiasExtensionPlugin

    setup = PluginSetup("bias_extension", 230.0, 115.0, (0.0, 90.0), {"clamp": "position"})
    with pytest.raises(
        DataError,
        match=r"experiment.toml: \[specimen\] fibre_angles_deg = "
        r"\[0.0, 90.0\]: bias test: fibres at 0 deg to the load run from clamp",
    ):
        BiasExtensionPlugin.check_specimen(setup, "experiment.toml")
    BiasExtensionPlugin.check_specimen(
        PluginSetup("bias_extension", 230.0, 115.0, (45.0, 135.0), {"clamp": "position"}),
        "experiment.toml",
    )


def test_short_specimen_gets_the_corner_lines_and_does_not_lock():
    """187 × 119 mm at h = 17 (no corner-to-corner lattice; too short for the lattice pair's
    band to lie in the centre zone): the mesh has the fibre lines through the corners as edges
    (kind "zones") and at K/k_s = 10⁶ its force equals that of the aligned mesh at h = 15 within
    0.1 % (the old gmsh fallback: 127 times it, benchmarks/locking.py --zones)."""

    def force(h):
        b = BiasExtension(
            [FibreStretch(k_l=1e6 * K_S, k_m=1e6 * K_S), Shear(k_s=K_S)],
            length=187.0,
            width=119.0,
            h=h,
            clamp="position",
        )
        return b.discretisation["mesh_kind"], b.run(20.0, 2).force[-1]

    (kind_a, f_a), (kind_z, f_z) = force(15.0), force(17.0)
    assert (kind_a, kind_z) == ("aligned", "zones")
    assert abs(f_z / f_a - 1.0) < 1e-3, (f_z, f_a)


@pytest.mark.parametrize("ratio, warned", [(1e4, False), (1e9, True), (math.inf, True)])
def test_aligned_lattice_off_the_fibre_angle_is_announced(ratio, warned):
    """At h = W/20 the 250 × 115 specimen's corner-to-corner lattice is at 45.034°, within the
    0.05° the builder accepts, not at the fibres' 45°: the fibres then cross its edges and the
    force grows with K (measured: 0.3 % above the limit at K/k_s = 10⁶, 57 % at 10⁹; silent
    before). Asked for by name (``auto`` skips it: next test), K/k_s · δ² above 1 is warned as
    may-lock, with the mismatch in the record."""
    fibres = (
        FibreStretch(inextensible=True)
        if math.isinf(ratio)
        else FibreStretch(k_l=ratio * K_S, k_m=ratio * K_S)
    )
    b = BiasExtension(
        [fibres, Shear(k_s=K_S)],
        length=250.0,
        width=115.0,
        h=5.75,
        clamp="position",
        mesh="aligned",
    )
    d = b.discretisation
    assert d["mesh_kind"] == "aligned"
    assert d["angle_mismatch_deg"] == pytest.approx(0.0337, abs=1e-4)
    assert d["may_lock"] is warned
    assert ("LOCKED" in d["notice"] and "45.0337" in d["notice"]) is warned


@pytest.mark.parametrize("ratio, kind", [(1e6, "aligned"), (1e9, "lattice_pair")])
def test_auto_skips_a_lattice_off_the_fibre_angle_that_would_lock(ratio, kind):
    """``auto`` takes the 45.034° lattice of 250 × 115 at h = W/20 only where K/k_s · δ² ≤ 1
    (δ = 0.034°: up to K/k_s ≈ 2.9·10⁶), else the lattice pair, whose angle is exact, and says
    so. At K/k_s = 10⁹ the force on the skipped lattice was 1.573 × the three-zone force; on
    the lattice pair it is within 1e-4 of it (measured 0.99998), and 0.3 % above at 10⁶ on the
    lattice kept (K/k_s · δ² = 0.35)."""
    b = BiasExtension(
        [FibreStretch(k_l=ratio * K_S, k_m=ratio * K_S), Shear(k_s=K_S)],
        length=250.0,
        width=115.0,
        h=5.75,
        clamp="position",
    )
    d = b.discretisation
    assert d["mesh_kind"] == kind and not d["may_lock"]
    assert ("0.0337 deg off the fibres" in d["notice"]) is (kind == "lattice_pair")
    assert 0.99 < force_ratio(b) < (1.004 if kind == "aligned" else 1.0001)


@pytest.mark.parametrize(
    "length, width, kind",
    [
        (250.0, 115.0, "lattice_pair"),
        (320.0, 100.0, "lattice_pair"),
        (215.0, 70.0, "lattice_pair"),
        (400.0, 105.0, "lattice_pair"),
        (345.0, 115.0, "aligned"),
        (460.0, 115.0, "aligned"),
    ],
)
def test_exact_inextensibility_holds_on_the_fibre_aligned_meshes(length, width, kind):
    """The exact constraint at h = W/10, on specimens with a centre zone (L > 2W), on the lattice
    pair and on a corner-to-corner lattice. Before the bow penalty (discretise/energy.py) the
    multiplier iteration stalled on 11 of 17 such sizes, the aligned 345 × 115 among them; on
    250 × 115 it stalled at |λ − 1| = 1.2e-9 until the augmentation stiffened. Now every
    quadrature point keeps |λ − 1| ≤ 1e-9, the force lies within 0.7 % below the three-zone
    idealisation (as the elastic fibres' force at K/k_s = 10⁹ does on these sizes), and
    nothing warns."""
    b = BiasExtension(
        [FibreStretch(inextensible=True), Shear(k_s=K_S)],
        length=length,
        width=width,
        h=width / 10,
        clamp="position",
    )
    d = b.discretisation
    assert d["mesh_kind"] == kind and not d["may_lock"] and "WARNING" not in d["notice"]
    assert 0.993 < force_ratio(b, steps=6) < 1.0 + 1e-6
    assert max(m.violation() for m in b.problem.energy.multipliers) <= 1e-9


def test_bow_penalty_vanishes_at_the_exact_solution():
    """The bow penalty ½ β S h² |H|² holds a P2 fibre edge's sideways bow at first order; at
    the constrained solution the cells are affine (λ = μ = 1 at their quadrature points), so it
    carries nothing: below 1e-7 of the cell energy (measured 1.0e-8 at β = 1e3, 1.0e-9 at
    β = 1e4), and the force is the limit of elastic fibres (K/k_s = 10⁹ on the same mesh:
    1.2e-5 apart, the elastic fibres' own stretch)."""

    def run(fibres):
        b = BiasExtension(
            [fibres, Shear(k_s=K_S)], length=345.0, width=115.0, h=11.5, clamp="position"
        )
        return b, b.run(0.13 * 345.0, 6).force[-1]

    b, exact = run(FibreStretch(inextensible=True))
    e = b.problem.energy
    comm = b.specimen.mesh.comm
    bow = comm.allreduce(fem.assemble_scalar(fem.form(e.bow_penalty() * e.dx)))
    total = comm.allreduce(fem.assemble_scalar(fem.form(e.cell_energy())))
    assert 0.0 <= bow < 1e-7 * total
    _, elastic = run(FibreStretch(k_l=1e9 * K_S, k_m=1e9 * K_S))
    assert abs(exact / elastic - 1.0) < 1e-4


@pytest.mark.parametrize(
    "length, width, theta, frac", [(250.0, 115.0, 60.0, 0.13), (380.0, 100.0, 30.0, 0.04)]
)
def test_exact_inextensibility_at_other_fibre_angles(length, width, theta, frac):
    """The exact constraint at ±60° and ±30° on the default mesh at W/10 (the lattice pair) is
    the limit of elastic fibres, K/k_s = 10⁹ on the same mesh (their own stretch is ~1e-9).
    At ±30° every load step failed down to a load of 5e-4 mm before the Newton solves after a
    multiplier update measured their tolerance from the step's first residual
    (discretise/solver.py): the stiffened augmentation's rounding floor (6e-10) lay above the
    1e-13 their own initial residual asked for."""

    def run(fibres):
        b = BiasExtension(
            [fibres, Shear(k_s=K_S)],
            length=length,
            width=width,
            h=width / 10,
            clamp="position",
            fibre_angles=(theta, -theta),
        )
        return b, b.run(frac * length, 4).force[-1]

    b, exact = run(FibreStretch(inextensible=True))
    d = b.discretisation
    assert d["mesh_kind"] == "lattice_pair" and not d["may_lock"]
    assert max(m.violation() for m in b.problem.energy.multipliers) <= 1e-9
    _, elastic = run(FibreStretch(k_l=1e9 * K_S, k_m=1e9 * K_S))
    assert abs(exact / elastic - 1.0) < 1e-4, (exact, elastic)


@pytest.mark.parametrize(
    "length, width, theta, frac, h_ref",
    [(250.0, 115.0, 60.0, 0.13, 3.9), (380.0, 100.0, 30.0, 0.04, 3.0)],
)
def test_other_fibre_angles_against_the_converged_aligned_lattice(
    length, width, theta, frac, h_ref
):
    """Fibres at ±60° and ±30° (the three-zone formula is for ±45°): the default mesh at W/10
    (the lattice pair: no corner-to-corner lattice fits there) against the corner-to-corner
    lattice at about W/30 (within 0.005° of the fibres: K/k_s · δ² ≤ 0.006), K/k_s = 10⁶.
    The aligned forces still move by 4e-4 between h ≈ 3.8 and 3.2 mm at ±30°, so 2e-3 is the
    reference's own uncertainty, not a tolerance of the lattice pair (measured 1.0001 at ±60°,
    1.0006 at ±30°); gmsh's mesh at W/10 gave 2.49 and 4.09 times the reference. ±30° stays
    below ū = 0.04·L, short of the net's kinematic limit."""

    def force(h, mesh):
        b = BiasExtension(
            [FibreStretch(k_l=1e6 * K_S, k_m=1e6 * K_S), Shear(k_s=K_S)],
            length=length,
            width=width,
            h=h,
            clamp="position",
            fibre_angles=(theta, -theta),
            mesh=mesh,
        )
        return b.discretisation, b.run(frac * length, 4).force[-1]

    (d, f), (d_ref, f_ref) = force(width / 10, "auto"), force(h_ref, "aligned")
    assert d["mesh_kind"] == "lattice_pair" and not d["may_lock"]
    assert d_ref["angle_mismatch_deg"] < 5e-3
    assert abs(f / f_ref - 1.0) < 2e-3, (f, f_ref)
