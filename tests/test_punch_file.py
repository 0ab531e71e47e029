"""A user's punch or die as a file through the same command as the hemisphere: ``[tooling]
punch_file`` and ``punch_units`` (or ``die_file`` and ``die_units``) in experiment.toml (a path
relative to it), read and checked with the data, the forming solved with the tool tabulated from
the file (forming/tabulated_tools.py).

* ``fabricsurf compare`` on hemisphere data whose experiment.toml names an STL punch (the
  plug-in's hemisphere, written in cm to check the unit): it runs, and its punch force is that
  of the analytic punch to the facets' error (the largest difference over the steps over the
  final force: 1.0e-2 with 2 mm meridian edges, as tests/test_surface_punch.py measured;
  bound 2e-2);
* a punch_file without punch_units, a file that is not there and a surface that is not closed
  are refused by the data loader, naming the key or the file, before any solve;
* a punch file in mm read as cm, ten times too large (within the scale check's factor of 50),
  is refused by the checks that compare, fit and diagnose make of the data: its hemisphere of
  radius 200 mm would pass through the die's 22 mm opening, which stops it at a stroke of
  1.43 mm (the sphere; 1.61 mm for its 20 mm facets, inscribed, 0.25 mm lower), below the
  data's 4 mm.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from hemisphere_case import BLANK, PARAMS, TOOLS, H, R
from mpi4py import MPI

from fabricsurf.cli import main
from fabricsurf.errors import InputError
from fabricsurf.experiments.forming.surfaces import files, meshes
from fabricsurf.inverse.contract.data import load_experiment, write_experiment
from fabricsurf.inverse.fitting.preconditions import check_in_loop
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import formed_part as sf
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist

COMM = MPI.COMM_WORLD
EDGE = 2.0
TOOLING = TOOLS
FACET_TOL = 2e-2
"""The triangulated punch's largest force difference over the steps, relative to the final
force (module docstring; at the first contact, 2 mm, the force is a sixth of the final one and
the facets' sagitta a larger part of its penetration)."""


def model():
    return [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]


def with_tooling(directory: Path, lines: str) -> None:
    """Add ``lines`` to the [tooling] table of ``directory``/experiment.toml."""
    toml = directory / "experiment.toml"
    toml.write_text(toml.read_text().replace("[tooling]\n", f"[tooling]\n{lines}\n"))


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """``data``: hemisphere data of the analytic punch; ``stl``: the same with the punch as
    an STL file in cm; ``nounits``, ``absent``, ``open``: bad punch files."""
    base = Path(COMM.bcast(str(tmp_path_factory.mktemp("punch")) if COMM.rank == 0 else None))
    exp = sf.hemisphere_template(BLANK, TOOLING, [2.0, 4.0], sf.part_points(BLANK, R, 4))
    exp = sf.add_forming_noise(sf.forming_data(exp, model(), H, COMM), 0.01, 0.05, 1)
    if COMM.rank == 0:
        v, f = meshes.hemisphere_punch_mesh(R, EDGE)
        names = ("data", "stl", "nounits", "absent", "open", "tenfold", "die", "dienounits")
        for name in (*names, "holder", "holdernounits"):
            write_experiment(base / name, exp, overwrite=True)
        files.write_stl(base / "stl" / "punch.stl", 0.1 * v, f)  # in cm
        with_tooling(base / "stl", 'punch_file = "punch.stl"\npunch_units = "cm"')
        files.write_stl(base / "nounits" / "punch.stl", v, f)
        with_tooling(base / "nounits", 'punch_file = "punch.stl"')
        with_tooling(base / "absent", 'punch_file = "nothere.stl"\npunch_units = "mm"')
        cap = f[np.all(v[f][:, :, 2] > -R - 1e-9, axis=1)]  # the cap alone: not closed
        files.write_stl(base / "open" / "punch.stl", v, cap)
        with_tooling(base / "open", 'punch_file = "punch.stl"\npunch_units = "mm"')
        files.write_stl(base / "tenfold" / "punch.stl", v, f)  # in mm, read as cm
        with_tooling(base / "tenfold", 'punch_file = "punch.stl"\npunch_units = "cm"')
        die = meshes.die_plate_mesh(R + TOOLS["clearance"], TOOLS["die_lip"], 45.0, 8.0, 1.0, 150)
        files.write_stl(base / "die" / "die.stl", *die)
        with_tooling(base / "die", 'die_file = "die.stl"\ndie_units = "mm"')
        files.write_stl(base / "dienounits" / "die.stl", *die)
        with_tooling(base / "dienounits", 'die_file = "die.stl"')
        holder = meshes.holder_plate_mesh(
            R + TOOLS["clearance"], TOOLS["die_lip"], 65.0, 8.0, 1.0, 160
        )
        files.write_stl(base / "holder" / "holder.stl", *holder)
        files.write_stl(base / "holder" / "die.stl", *die)
        both = 'die_file = "die.stl"\ndie_units = "mm"\nholder_file = "holder.stl"\n'
        with_tooling(base / "holder", both + 'holder_units = "mm"')
        files.write_stl(base / "holdernounits" / "holder.stl", *holder)
        with_tooling(base / "holdernounits", 'holder_file = "holder.stl"')
        (base / "p.json").write_text(json.dumps(PARAMS))
    COMM.barrier()
    return base


@pytest.mark.parametrize(
    "case, key, tool",
    [("stl", "punch_file", "punch.stl"), ("die", "die_file", "die.stl")],
)
def test_tool_file_through_compare(root, case, key, tool):
    """The command line's compare takes the file from experiment.toml; its forces are the
    analytic tool's to the facets' error: the punch's (meridian edges 2 mm, 1.0e-2 of the
    final force), or the die's (the plate about the opening, lip edges 1 mm: 9.2e-3,
    tests/test_surface_die.py), which is not the analytic die itself (above 1e-4)."""
    out = root / f"{case}_out{COMM.size}"
    argv = ["compare", str(root / case), "--params", str(root / "p.json"), "--h", str(H)]
    assert main([*argv, "--out", str(out)]) == 0
    exp = load_experiment(root / case)
    assert exp.setup.options[key] == str(root / case / tool)
    with ForwardModel(exp, model(), H, COMM) as fm:
        tabulated = fm.run().force
    with ForwardModel(load_experiment(root / "data"), model(), H, COMM) as fm:
        analytic = fm.run().force
    assert 1e-4 * analytic[-1] < np.abs(tabulated - analytic).max() < FACET_TOL * analytic[-1]
    assert (out / "misfit.json").is_file()


def test_holder_file_through_compare(root):
    """The holder as the analytic one's plate (outline in 160 segments, lip edges 1 mm) in an
    STL file, beside the die's (the ``die`` case's): compare takes both from experiment.toml,
    and the forces are those under the same die and the analytic holder to the holder's facets'
    error (below 1e-3 of the final force, as the ring's of tests/test_surface_holder.py, whose
    forms these are: a die and a holder through tables)."""
    out = root / f"holder_out{COMM.size}"
    argv = ["compare", str(root / "holder"), "--params", str(root / "p.json"), "--h", str(H)]
    assert main([*argv, "--out", str(out)]) == 0
    exp = load_experiment(root / "holder")
    assert exp.setup.options["holder_file"] == str(root / "holder" / "holder.stl")
    with ForwardModel(exp, model(), H, COMM) as fm:
        tabulated = fm.run().force
    with ForwardModel(load_experiment(root / "die"), model(), H, COMM) as fm:
        analytic = fm.run().force
    error = np.abs(tabulated - analytic).max() / analytic[-1]
    print(f"holder file against the analytic holder: {error:.3g} of the final force")
    assert error < 1e-3
    assert (out / "misfit.json").is_file()


@pytest.mark.parametrize(
    "case, words",
    [
        ("nounits", r"punch_file = '.*/nounits/punch.stl' needs punch_units.*none given"),
        ("absent", r"punch_file: .*nothere.stl: no such file"),
        ("open", r"punch.stl.*not closed"),
        ("dienounits", r"die_file = '.*/dienounits/die.stl' needs die_units.*none given"),
        ("holdernounits", r"holder_file = '.*/holder.stl' needs holder_units.*none given"),
    ],
)
def test_bad_punch_files_refused_with_the_data(root, case, words):
    with pytest.raises(InputError, match=words):
        load_experiment(root / case)


def test_punch_through_the_die_refused_before_comparing(root):
    """The punch file in mm read as cm (module docstring), named with the data's step."""
    exp = load_experiment(root / "tenfold")
    with pytest.raises(
        InputError,
        match=r"step 2: .*punch.stl: the stroke of 4 mm passes through the die plate with a "
        r"circular opening of radius 22 mm.*stops it at a stroke of 1\.6",
    ):
        check_in_loop([exp])


def test_punch_file_read_once(tmp_path, monkeypatch):
    """The options' check, the plug-in's tools, its die and symmetry checks and the data's
    check all ask for the punch: the file is read once (a file of 6·10⁶ triangles takes about
    a minute to read), and read again once it has changed."""
    from fabricsurf.experiments.base import PluginSetup
    from fabricsurf.experiments.hemisphere import HemispherePlugin

    path = tmp_path / "punch.stl"
    files.write_stl(path, *meshes.hemisphere_punch_mesh(R, 2.0))
    reads = []
    original = files.read_surface
    monkeypatch.setattr(files, "read_surface", lambda *a, **k: reads.append(a) or original(*a, **k))
    tooling = {**TOOLS, "punch_file": str(path), "punch_units": "mm"}
    opts = HemispherePlugin.parse_options({"tooling": tooling}, 1.0, "t")
    setup = PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts)
    HemispherePlugin.check_data(setup, [0, 1], [0.0, 2.0], "force.csv")
    with HemispherePlugin(setup, model(), H, MPI.COMM_WORLD) as e:
        assert e.domain == "quarter"
    assert len(reads) == 1
    files.write_stl(path, *meshes.hemisphere_punch_mesh(R, 1.5))
    HemispherePlugin.parse_options({"tooling": tooling}, 1.0, "t")
    assert len(reads) == 2
