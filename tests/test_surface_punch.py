"""The hemisphere forming plug-in with its punch given as a surface
(fabricsurf/experiments/forming/tabulated_tools.py): the punch's distance and normal tabulated
at the quadrature points from numpy, refreshed at every Newton iteration.

Checks that can fail independently of each other:
* the analytic punch given through the table (analytic.HemispherePunch) forms the blank as the
  UFL punch does: the punch force at every step and the largest penetration agree to the
  Newton tolerance, with the same Newton iterations give or take two (the table's Jacobian
  leaves out the tool's curvature term);
* the punch as an STL file (binary, the hemisphere on its shank closed by a flat bottom:
  meshes.hemisphere_punch_mesh, written and read back) converges to it as the triangles
  shrink: the force and the shear along the diagonal approach the analytic punch's, the force
  error falling at about rate 2 in the edge length (the facets' sagitta h²/8R);
* a flat-ended punch with a filleted edge (a shape with no formula in the plug-in): the punch
  work equals the change of the energy, the trapezoid rule's error falling at rate 2;
* 1 = 2 ranks: the triangulated punch's forces agree between serial and two ranks (the same
  file under ``mpirun -n 2``: the tabulation is cell by cell on each rank);
* friction on the punch through a second table of the punch at the step's start: the analytic
  punch given through the tables forms as the UFL punch does with μ_p = 0.3;
* a punch in the wrong units and a punch that starts inside the blank are refused before
  forming, with messages naming them.

Measured (R = 20 mm, 60 mm blank, h = 4 mm, stroke 4 mm in 4 steps, ±45°): final force
0.946034 N analytic and tabulated (relative 6e-12); triangulated with meridian edges 2, 1,
0.5 mm: 0.936363, 0.942550, 0.945433 N, relative errors over the steps 1.02e-2, 3.68e-3,
6.35e-4 (rates 1.47, 2.54; 2.0 over the two halvings); 17/13/14/12 Newton iterations per step
against 19/13/14/12 analytic.
"""

import h5py
import numpy as np
import pytest
from hemisphere_case import BLANK, FRICTION, TOOLING, H, R, work_balance_errors
from mpi4py import MPI

from fabricsurf.errors import DataError, InputError
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming.surfaces import analytic, files, meshes
from fabricsurf.experiments.forming.surfaces.triangulated import TriangulatedSurface
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist

COMM = MPI.COMM_WORLD
STROKE, STEPS = 4.0, 4
SERIAL_FORCES_STL_1MM = [0.0, 0.02839872, 0.14937305, 0.43828008, 0.94254979]
"""The triangulated punch's (edges 1 mm) forces in serial, N (module docstring)."""


def stl_punch(folder, h: float) -> TriangulatedSurface:
    """meshes.hemisphere_punch_mesh written to a binary STL file (float32 corners) in mm and
    read back as a tool."""
    path = folder / f"punch_{h:g}mm.stl"
    files.write_stl(path, *meshes.hemisphere_punch_mesh(R, h))
    return files.read_surface(path, units="mm")


def written_pressure(e, path) -> np.ndarray:
    """The contact pressure of ``e``'s state as its XDMF writer stores it, read back from the
    HDF5 file (the P1 nodal values of the file's only time), ordered by the nodes' positions:
    the file orders them by rank, and two runs on 2 ranks may partition the mesh differently."""
    w = e.writer(path)
    try:
        w.write(STROKE)
    finally:
        w.close()
    with h5py.File(path.with_suffix(".h5"), "r") as f:
        (data,) = f["Function/contact_pressure"].values()
        (mesh,) = f["Mesh"].values()
        p, x = np.asarray(data).ravel(), np.asarray(mesh["geometry"])
    return p[np.lexsort(x.T[::-1])]


def form(surface=None, xdmf=None) -> dict:
    opts = dict(TOOLING)
    if surface is not None:
        opts["punch_surface"] = surface
    model = [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]
    e = HemispherePlugin(
        PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model, H, COMM
    )
    try:
        e.set_load(0.0)
        e.run(STROKE, STEPS)
        return {
            "force": np.array(e.force),
            "penetration": e.max_penetration(),
            "iterations": [s["newton_iterations"] for s in e.steps],
            "shear": e.profile(e.diagonal_deg, np.linspace(1.0, 12.0, 12))["shear_deg"],
            "pressure": None if xdmf is None else written_pressure(e, xdmf),
        }
    finally:
        e.close()


@pytest.fixture(scope="module")
def analytic_run(tmp_path_factory):
    return form(xdmf=_shared(tmp_path_factory) / "analytic.xdmf")


def _shared(factory):
    """A directory every rank writes the same file into (rank 0's)."""
    return COMM.bcast(factory.mktemp("punch") if COMM.rank == 0 else None)


def test_tabulated_analytic_punch_is_the_punch(analytic_run, tmp_path_factory):
    """Also the fields a forming engineer opens in ParaView: the contact pressure written to
    the XDMF file is the UFL punch's (the table's distance is refreshed at the converged
    state before the fields are projected)."""
    tab = form(analytic.HemispherePunch(R), xdmf=_shared(tmp_path_factory) / "tabulated.xdmf")
    p = analytic_run["pressure"]
    assert p.max() > 0.0
    assert np.abs(tab["pressure"] - p).max() < 1e-6 * p.max()
    f = analytic_run["force"]
    assert np.abs(tab["force"] - f).max() < 1e-8 * f[-1]
    assert abs(tab["penetration"] - analytic_run["penetration"]) < 1e-9
    assert np.abs(tab["shear"] - analytic_run["shear"]).max() < 1e-6
    assert all(abs(a - b) <= 2 for a, b in zip(tab["iterations"], analytic_run["iterations"]))


@pytest.mark.serial("the serial forces are the reference of the 2-rank check below")
def test_triangulated_punch_converges(analytic_run, tmp_path):
    f = analytic_run["force"]
    errors, shear = [], []
    for h in (2.0, 1.0):
        run = form(stl_punch(tmp_path, h))
        errors.append(np.abs(run["force"] - f).max() / f[-1])
        shear.append(np.abs(run["shear"] - analytic_run["shear"]).max())
        if h == 1.0:
            assert np.allclose(run["force"], SERIAL_FORCES_STL_1MM, rtol=1e-6, atol=1e-9)
    assert errors[1] < 0.5 * errors[0] and errors[1] < 5e-3, errors
    assert shear[1] < shear[0] and shear[1] < 0.1, shear


def test_two_ranks_agree(tmp_path):
    """Serial or two ranks: the triangulated punch's forces are the serial ones (each rank
    reads its own copy of the file)."""
    run = form(stl_punch(tmp_path, 1.0))
    assert np.allclose(run["force"], SERIAL_FORCES_STL_1MM, rtol=1e-6, atol=1e-9)


def test_flat_punch_work_balance():
    """A punch of a shape the plug-in has no formula for: a cylinder of radius 15 mm with its
    end edge rounded to 5 mm (a flat-ended punch). The punch force is the work conjugate of the
    stroke whatever the shape: the punch work ∫ F ds equals the change of the energy, the
    trapezoid rule's error falling at rate 2 with the step (measured 0.160, 0.0406 N·mm in 4
    and 8 steps to 4 mm, rate 1.98, against a work of 3.41 N·mm)."""
    punch = analytic.Cylinder(15.0, origin=(0.0, 0.0, -20.0), length=40.0, fillet=5.0)
    opts = {**TOOLING, "punch_surface": punch}
    model = [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]
    e = HemispherePlugin(
        PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model, H, COMM
    )
    try:
        errors, change = work_balance_errors(e, STROKE, (4, 8))
    finally:
        e.close()
    assert change > 1.0 and errors[0] > 0
    assert 1.9 < np.log2(errors[0] / errors[1]) < 2.1, errors


def formed_with_friction(surface, mus: tuple) -> list[dict]:
    """Punch force and dissipation of forming with the holder's friction (10 kPa, μ = 0.3) and
    each punch friction of ``mus`` in turn, on one experiment (the coefficient a fem.Constant)."""
    opts = {**TOOLING, **FRICTION}
    if surface is not None:
        opts["punch_surface"] = surface
    model = [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]
    e = HemispherePlugin(
        PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model, H, COMM
    )
    runs = []
    try:
        for mu in mus:
            e.tools.mu_punch.value = mu
            e.set_load(0.0)
            e.solver.u.x.array[:] = 0.0
            e.run(STROKE, STEPS)
            runs.append({"force": np.array(e.force), "dissipated": e.dissipated()})
    finally:
        e.close()
    return runs


def test_punch_friction_through_table():
    """Coulomb friction on a punch given as a surface: its pressure and normal at the step's
    start come from a second table of the punch, made at the last converged state, where the
    tabulated distance is exact. Through the table the analytic hemisphere gives the UFL
    punch's forces and dissipation with μ_p = 0.3, to the Newton tolerance, a hundred times
    closer than the punch friction's own effect on them (its μ_p = 0 run on the same table)."""
    (ufl_punch,) = formed_with_friction(None, (0.3,))
    table, frictionless = formed_with_friction(analytic.HemispherePunch(R), (0.3, 0.0))
    f = ufl_punch["force"]
    effect = np.abs(table["force"] - frictionless["force"]).max()
    gap = np.abs(table["force"] - f).max()
    print(f"force {f[-1]:.8g} N; table against UFL {gap:.3g}; friction's effect {effect:.3g} N")
    assert effect > 1e-5 * f[-1] and gap < 1e-2 * effect and gap < 1e-8 * f[-1]
    d, d0 = ufl_punch["dissipated"], frictionless["dissipated"]
    assert table["dissipated"] > d0 and abs(table["dissipated"] - d) < 1e-2 * (d - d0)


def test_bad_punches_refused():
    """Units that make the punch a thousand times too large, and a punch that starts 2 mm
    inside the blank, are refused before forming, on every rank."""
    model = [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0)]
    v, f = meshes.hemisphere_punch_mesh(R, 4.0)
    for surface, words in [
        (
            TriangulatedSurface(1000.0 * v, f, "punch_in_m.stl"),
            r"punch_in_m.stl: .*1e\+03 times larger than the blank \(60000 mm against 60 mm\)",
        ),
        (
            analytic.Moved(analytic.HemispherePunch(R), (0.0, 0.0, 2.0)),
            r"starts inside the blank.*2 mm deep",
        ),
    ]:
        opts = {**TOOLING, "punch_surface": surface}
        with pytest.raises(InputError, match=words):
            HemispherePlugin(
                PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model, H, COMM
            )


def test_punch_wider_than_the_opening_refused_at_the_stroke_the_die_stops_it():
    """A spherical punch of radius 26 mm against the die's opening of 22 mm (R = 20 mm,
    clearance and lip 2 mm): it first touches the lip torus (tube radius r_d = 2 about the
    circle ρ₀ = 24 mm at z_t = r_d − p_h/k_c) where its centre, at s − 26, lies 26 + r_d from
    that circle, at the stroke s* = z_t + 26 − √(28² − 24²) = 13.5778 mm. A run to a larger
    stroke is refused before any solve, naming that stroke; the sampled points (a 0.5 mm grid,
    a quarter of the lip radius, projected onto the sphere) lie within 0.35 mm of the first
    contact, whose stroke they then overestimate by at most 0.35² (1/26 + 1/2) / 2 = 0.033 mm."""
    z_t = TOOLING["die_lip"] - TOOLING["holder_pressure"] / TOOLING["contact_stiffness"]
    exact = z_t + 26.0 - np.sqrt(28.0**2 - 24.0**2)
    opts = {**TOOLING, "punch_surface": analytic.Sphere(26.0, (0.0, 0.0, -26.0))}
    model = [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0)]
    e = HemispherePlugin(
        PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model, H, COMM
    )
    try:
        e.check_stroke(13.5)
        with pytest.raises(InputError, match=r"sphere of radius 26 mm: the stroke of 20 mm") as err:
            e.run(20.0, 4)
        stop = float(str(err.value).split("stroke of ")[-1].split(" mm")[0])
        assert 0.0 <= stop - exact < 0.033, (stop, exact)
        assert e.steps == []  # refused before the first step
    finally:
        e.close()


def test_lopsided_punch_is_not_solved_on_the_quarter():
    """A square ±45° blank is solved on its quarter only if the punch given as a surface is its
    own mirror image in both mid-planes (checks.mirror_asymmetry): a sphere 0.5 mm off the axis
    makes ``auto`` choose the full blank, and ``quarter`` is refused naming the plane."""
    from fabricsurf.experiments.forming import blank as forming_blank

    def setup(centre, domain="auto"):
        opts = {**TOOLING, "punch_surface": analytic.Sphere(20.0, centre), "blank_domain": domain}
        return PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts)

    assert forming_blank.domain(setup((0.0, 0.0, -20.0)), H) == "quarter"
    assert forming_blank.domain(setup((0.5, 0.0, -20.0)), H) == "full"
    with pytest.raises(DataError, match=r"'quarter': sphere .* not mirror-symmetric about x = 0"):
        forming_blank.domain(setup((0.5, 0.0, -20.0), "quarter"), H)
