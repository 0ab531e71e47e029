"""docs/dic.md: DIC exports as they are written → the measurement contract. Synthetic exports
(fabricsurf.inverse.dic.export, in each layout, in pixels, in a tilted camera frame, with
holes) are imported and the field compared with the generator's displacements; each bad input
gets its message (file, line, key, value). No FEniCSx solve: numpy only."""

import re

import numpy as np
import pytest
from mpi4py import MPI

from fabricsurf.cli import main
from fabricsurf.errors import DataError
from fabricsurf.inverse.contract.data import load_experiment
from fabricsurf.inverse.dic.binning import noise_estimate
from fabricsurf.inverse.dic.description.spec import read_spec
from fabricsurf.inverse.dic.export import write_images
from fabricsurf.inverse.dic.frame import Frame
from fabricsurf.inverse.dic.importer import import_dic
from fabricsurf.inverse.dic.layouts import LAYOUTS, custom_layout

COMM = MPI.COMM_WORLD
SERIAL = pytest.mark.serial(
    "numpy on one process, nothing shared between ranks; the 2-rank "
    "path is test_command_writes_a_contract_directory's"
)
L, W = 120.0, 80.0
PATH = [2.0, 4.0, 6.0]
SPACING = 1.0  # mm between the DIC points


def grid(spacing=SPACING, margin=1.0):
    xs = np.arange(margin, L - margin + 1e-9, spacing)
    ys = np.arange(margin, W - margin + 1e-9, spacing)
    return np.array([(a, b) for a in xs for b in ys])


def linear(X, t):
    """A field linear in X (binning reproduces it exactly at the bins' mean points)."""
    return np.column_stack(
        [t * X[:, 0] / L + 0.01 * t * X[:, 1], -0.003 * t * (X[:, 1] - W / 2) + 0.002 * t * X[:, 0]]
    )


def quadratic(X, t):
    return np.column_stack([t * (X[:, 0] / L) ** 2, 0.0 * X[:, 1]])


PIXELS = Frame(0.05, True, (200.0, 2000.0), "left", 2.5)  # 0.05 mm/pixel, tilted 2.5°


def spec_text(layout="dice", files="img/*", frame=PIXELS, extra="", steps=None, units=None):
    if units is None:
        units = f"mm_per_pixel = {frame.scale}" if frame.scale != 1.0 else ""
    tilt = "" if frame.tilt_deg is None else f"angle_deg = {frame.tilt_deg}"
    steps = steps or "images = [1, 2, 3]\npath = [2.0, 4.0, 6.0]"
    return f"""name = "dic-test"
[export]
layout = "{layout}"
files = "{files}"
[units]
{units}
[frame]
origin = [{frame.origin[0]}, {frame.origin[1]}]
grip = "{frame.grip}"
y_down = {str(frame.y_down).lower()}
{tilt}
[specimen]
length = {L}
width = {W}
fibre_angles_deg = [45.0, -45.0]
[loading]
test = "bias_extension"
[steps]
{steps}
{extra}
"""


def make(
    d,
    layout="dice",
    frame=PIXELS,
    field=linear,
    holes=0.05,
    points=None,
    text=None,
    noise=0.0,
    images=(1, 2, 3),
):
    """Write a synthetic export and its dic.toml in ``d``; returns the spec path and points."""
    X = grid() if points is None else points
    rng = np.random.default_rng(7)
    Us = [field(X, t) + rng.normal(0, noise, X.shape) if noise else field(X, t) for t in PATH]
    lay = LAYOUTS[layout] if isinstance(layout, str) else layout
    write_images(d / "img", lay, frame, list(images), X, Us, holes=holes, seed=3)
    spec = d / "dic.toml"
    spec.write_text(text or spec_text(lay.name, frame=frame))
    return spec, X


def field_error(exp, field):
    return max(
        np.abs(exp.u[exp.step_rows(s)] - field(exp.X[exp.step_rows(s)], t)).max()
        for s, t in zip(exp.steps, exp.path)
    )


def lost(path, layout):
    """Holes of one written file, counted independently of the importer."""
    text = path.read_text().splitlines()
    rows = [r for r in text if r.strip() and r.lstrip()[0] in "0123456789-+"]
    delim = ";" if layout.name in ("davis", "aramis_nodemap") else ","
    if layout.valid:
        return sum(float(r.split(delim)[-1]) == layout.invalid for r in rows)
    return sum("nan" in r for r in rows)


@SERIAL
@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_each_layout_round_trip(tmp_path, name):
    """Each layout's files (as its documentation shows them) → the generator's displacements
    at the generator's points: exact but for the %.10g printing (1e-6 mm), after the pixel
    scale, y flip, origin and 2.5° tilt; the holes are dropped and counted exactly."""
    lay = LAYOUTS[name]
    frame = PIXELS if lay.unit == "pixel" else Frame(1.0, False, (-30.0, 12.0), "left", 2.5)
    spec, X = make(tmp_path, name, frame)
    exp, rep = import_dic(read_spec(spec))
    assert field_error(exp, linear) < 1e-6
    files = sorted((tmp_path / "img").iterdir())
    holes = [lost(f, lay) for f in files]
    assert [e["holes"] for e in rep["files"]] == holes and min(holes) > 0
    assert [e["points"] for e in rep["files"]] == [len(X) - h for h in holes]
    assert len(exp.X) == 3 * len(X) - sum(holes)


@SERIAL
def test_columns_mapping_and_units_tags(tmp_path):
    """Any other layout through [columns]: names, a validity flag, pixel units."""
    table = {
        "x": "px",
        "y": "py",
        "u": "du",
        "v": "dv",
        "valid": "ok",
        "invalid": 0,
        "unit": "pixel",
    }
    lay = custom_layout(table, "t")
    extra = "[columns]\n" + "\n".join(
        f"{k} = {v!r}".replace("'", '"') if isinstance(v, str) else f"{k} = {v}"
        for k, v in table.items()
    )
    spec, _ = make(tmp_path, lay, text=spec_text("columns", extra=extra), holes=0.0)
    exp, _ = import_dic(read_spec(spec))
    assert field_error(exp, linear) < 1e-6


@SERIAL
def test_pixel_scale_and_frames_agree(tmp_path):
    """The same points written in mm (no tilt, y up) and in pixels (tilted, y down, the grip
    on the image's right edge) import to the same field."""
    mm = Frame(1.0, False, (0.0, 0.0), "left", 0.0)
    px = Frame(0.08, True, (1900.0, 100.0), "right", -4.0)
    out = []
    for k, fr in enumerate((mm, px)):
        d = tmp_path / str(k)
        spec, _ = make(d, "vic2d_metric" if k == 0 else "vic2d", fr, holes=0.0)
        out.append(import_dic(read_spec(spec))[0])
    a, b = (np.column_stack([e.field_step, e.X, e.u]) for e in out)
    a, b = (t[np.lexsort(np.round(t[:, :3], 6).T[::-1])] for t in (a, b))
    assert np.abs(a - b).max() < 1e-6


@SERIAL
def test_binning_bias_bound(tmp_path):
    """Binned to a 4 mm pitch: a linear field is reproduced at the bins' mean points; a
    quadratic one u = t (X/L)² is off by t/L² · var(X in bin) ≤ t/L² · p²/4, and is off (the
    test would pass with no binning otherwise)."""
    pitch = 4.0
    for field in (linear, quadratic):
        d = tmp_path / field.__name__
        spec, X = make(d, "dice", field=field, holes=0.0)
        spec.write_text(spec.read_text() + f"\n[binning]\npitch = {pitch}\n")
        exp, rep = import_dic(read_spec(spec))
        assert rep["files"][0]["bins"] == len(exp.step_rows(1)) < len(X) / 10
        err = field_error(exp, field)
        if field is linear:
            assert err < 1e-6
        else:
            assert 0.1 * PATH[-1] / L**2 * pitch**2 / 12 < err <= PATH[-1] / L**2 * pitch**2 / 4


@SERIAL
def test_noise_estimate(tmp_path):
    """σ = 0.02 mm of independent noise on the quadratic field: the estimate from the points
    (local planes in 4 × 4 cells) is within 10 %; binned to 2 mm (4 points a bin) it is the
    bins' σ/2, within 10 %; noise-free (linear) data get none (no scatter); a given noise_std is
    kept."""
    spec, X = make(tmp_path, "dice", field=quadratic, noise=0.02, holes=0.0)
    exp, rep = import_dic(read_spec(spec))
    assert rep["noise"]["method"].startswith("estimated") and exp.noise_std == pytest.approx(
        0.02, rel=0.1
    )
    spec.write_text(spec.read_text() + "\n[binning]\npitch = 2.0\n")
    exp, _ = import_dic(read_spec(spec))
    assert exp.noise_std == pytest.approx(0.01, rel=0.1)
    est = noise_estimate(np.ones(len(X), int), X, np.zeros((len(X), 2)))
    assert est["noise_std"] == 0.0
    exp, rep = import_dic(read_spec(make(tmp_path / "clean", "dice", field=linear)[0]))
    assert exp.noise_std is None and "no scatter" in rep["noise"]["method"]
    spec.write_text(spec.read_text() + "\n[data]\nnoise_std = 0.05\n")
    assert import_dic(read_spec(spec))[0].noise_std == 0.05


@SERIAL
def test_reference_images_give_the_noise(tmp_path):
    """Images without load (reference_images) are not steps; their displacements (noise only)
    give the noise level."""
    X = grid()
    rng = np.random.default_rng(1)
    Us = [rng.normal(0, 0.01, X.shape)] + [linear(X, t) for t in PATH]
    write_images(tmp_path / "img", LAYOUTS["dice"], PIXELS, [0, 1, 2, 3], X, Us, holes=0.02)
    spec = tmp_path / "dic.toml"
    spec.write_text(
        spec_text(steps="reference_images = [0]\nimages = [1, 2, 3]\npath = [2.0, 4.0, 6.0]")
    )
    exp, rep = import_dic(read_spec(spec))
    assert list(exp.steps) == [1, 2, 3] and len(rep["reference"]) == 1
    assert "reference" in rep["noise"]["method"]
    assert exp.noise_std == pytest.approx(0.01, rel=0.1)


# --- bad input: one message naming file, line or key, and the value -------------------------


def reject(spec, *patterns):
    with pytest.raises(DataError) as e:
        import_dic(read_spec(spec))
    for p in patterns:
        assert re.search(p, str(e.value)), (p, str(e.value))


def edit_file(path, line_no, new):
    lines = path.read_text().splitlines()
    lines[line_no - 1] = new
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture
def small(tmp_path):
    spec, _X = make(tmp_path, "dice", points=grid(spacing=4.0), holes=0.0)
    return spec, tmp_path / "img" / "DICe_solution_02.txt"


@SERIAL
def test_bad_cells_and_rows(small):
    spec, f = small
    head = (
        f.read_text()
        .splitlines()
        .index(next(r for r in f.read_text().splitlines() if r.startswith("COORD")))
        + 1
    )
    data_line = f.read_text().splitlines()[head + 4]
    cells = data_line.split(",")
    edit_file(f, head + 5, ",".join([cells[0], cells[1], "abc", *cells[3:]]))
    reject(spec, rf"DICe_solution_02.txt line {head + 5}: column 3 = 'abc' is not a number")
    edit_file(f, head + 5, ",".join(cells[:3]))
    reject(spec, rf"line {head + 5}: 3 fields, the header \(line {head}\) has 5")
    edit_file(f, head + 5, ",".join([cells[0], cells[1], "", "nan", cells[4]]))
    _exp, rep = import_dic(read_spec(spec))  # an empty or NaN cell is a hole
    assert rep["files"][1]["holes"] == 1 and rep["holes"] == 1
    lines = f.read_text().splitlines()
    f.write_text("\n".join(lines[:head] + [r + "," for r in lines[head:]]) + "\n")
    assert import_dic(read_spec(spec))[1]["holes"] == 1  # a delimiter ending every row
    edit_file(f, head + 5, lines[head + 1])
    reject(spec, rf"line {head + 5}: duplicated point .* also on line {head + 2}")


@SERIAL
def test_bad_header(small):
    spec, f = small
    f.write_text(f.read_text().replace("DISPLACEMENT_Y", "DISP_Y"))
    reject(spec, "DICe_solution_02.txt line 6: no column 'DISPLACEMENT_Y'")


@SERIAL
def test_outside_outline(small):
    spec, _f = small
    text = spec.read_text()
    spec.write_text(text.replace("origin = [200.0", "origin = [300.0"))
    reject(
        spec,
        r"DICe_solution_01.txt line \d+: point .* lies at \(X, Y\) = \(-",
        r"outside the specimen \[0, 120\] x \[0, 80\] mm",
    )
    spec.write_text(
        text.replace("origin = [200.0", "origin = [300.0").replace(
            "[frame]", '[frame]\noutside = "drop"'
        )
    )
    exp, rep = import_dic(read_spec(spec))
    assert rep["outside_dropped"] > 0 and exp.X[:, 0].min() >= 0


@SERIAL
def test_units_and_frame_keys(small):
    spec, f = small
    text = spec.read_text()
    spec.write_text(text.replace("mm_per_pixel = 0.05", ""))
    reject(spec, r"dic.toml: the coordinates are in pixels .* \[units\] mm_per_pixel is missing")
    spec.write_text(text.replace("angle_deg = 2.5", ""))
    reject(
        spec,
        r"DICe_solution_01.txt: the point cloud's long axis lies \+2.5\d° from",
        r"give \[frame\] angle_deg = 2.5",
    )
    spec.write_text(text.replace('grip = "left"', 'grip = "west"'))
    reject(spec, r"\[frame\] grip = 'west' is not one of")
    spec.write_text(text)
    lines = f.read_text().splitlines()
    cells = lines[9].split(",")
    edit_file(f, 10, ",".join([*cells[:2], "1e6", *cells[3:]]))  # pixels, 50 m
    reject(
        spec,
        r"DICe_solution_02.txt line 10: displacement of 5e\+04 mm, more than 10 times "
        r"the specimen size \(120 mm\): check \[units\]",
    )


@SERIAL
def test_lost_images_binning_and_scale(small):
    """An image that is all holes, bins no image fills, a pitch of half the specimen and a
    pixel scale 1000 times too small: each named before anything is written."""
    spec, f = small
    text = spec.read_text()
    lines = f.read_text().splitlines()
    head = lines.index(next(r for r in lines if r.startswith("COORD"))) + 1
    rows = [",".join(r.split(",")[:2] + ["nan"] * 3) for r in lines[head:]]
    original = f.read_text()
    f.write_text("\n".join(lines[:head] + rows) + "\n")
    reject(spec, rf"DICe_solution_02.txt: every one of its {len(rows)} rows is a hole")
    f.write_text(original)
    spec.write_text(text + "[binning]\npitch = 8.0\nmin_points = 50\n")
    reject(
        spec,
        r"DICe_solution_01.txt: no bin of \[binning\] pitch = 8 mm holds \[binning\] "
        r"min_points = 50 points",
    )
    spec.write_text(text + "[binning]\npitch = 45.0\n")
    reject(spec, r"\[binning\] pitch = 45 mm is more than half the specimen's 80 mm side")
    spec.write_text(text.replace("mm_per_pixel = 0.05", "mm_per_pixel = 0.00005"))
    reject(
        spec,
        r"DICe_solution_01.txt: the points span 0.11\d* x 0.07\d* mm of the 120 x 80 mm "
        r"specimen at 5e-05 mm per pixel",
    )


@SERIAL
def test_mixed_units(tmp_path):
    frame = Frame(1.0, False, (0.0, 0.0), "left", 0.0)
    spec, _ = make(tmp_path, "aramis_nodemap", frame, points=grid(spacing=4.0))
    f = sorted((tmp_path / "img").iterdir())[0]
    f.write_text(f.read_text().replace("u [mm]", "u [m]"))
    reject(spec, rf"{f.name} line 4: mixed units in the header \(x in mm, y in mm, u in m")
    f.write_text(f.read_text().replace("[mm]", "[pixel]").replace("u [m]", "u [pixel]"))
    reject(
        spec,
        rf"{f.name} line 4: the x column is in pixel but \[units\] coordinates is "
        '"mm"',
    )


@SERIAL
def test_steps_and_images(small):
    spec, f = small
    text = spec.read_text()
    spec.write_text(text.replace("images = [1, 2, 3]", "images = [1, 3, 2]"))
    reject(spec, r"\[steps\] images = \[1, 3, 2\]: steps out of order: step 3 is image 2")
    spec.write_text(
        text.replace(
            "images = [1, 2, 3]\npath = [2.0, 4.0, 6.0]", "images = [1, 2]\npath = [2.0, 4.0]"
        )
    )
    reject(spec, r"DICe_solution_03.txt: image 3 has no matching load step")
    spec.write_text(text.replace("images = [1, 2, 3]", "images = [1, 2, 4]"))
    reject(spec, r"image 3 has no matching load step")
    f.rename(f.with_name("DICe_solution_09.txt"))
    spec.write_text(text.replace("images = [1, 2, 3]", "images = [1, 3, 9]"))
    import_dic(read_spec(spec))  # the image number is the last integer in the name
    spec.write_text(text.replace("images = [1, 2, 3]", "images = [1, 3, 10]"))
    reject(spec, r"image 9 has no matching load step")
    spec.write_text(text.replace("path = [2.0, 4.0, 6.0]", "path = [2.0, 4.0]"))
    reject(spec, r"\[steps\] path has 2 values, \[steps\] images has 3")
    for g in sorted(f.parent.iterdir()):  # VIC-like names: image, then camera number
        g.rename(g.with_name(f"run-{int(g.stem.split('_')[-1]):04d}_0.txt"))
    spec.write_text(text.replace("images = [1, 2, 3]", "images = [1, 3, 9]"))
    reject(spec, r"run-0003_0.txt and run-0001_0.txt both give image 0 .* image_number")
    spec.write_text(
        text.replace("images = [1, 2, 3]", "images = [1, 3, 9]").replace(
            "[export]", '[export]\nimage_number = "-(\\\\d+)_"'
        )
    )
    assert len(import_dic(read_spec(spec))[0].steps) == 3


# --- the command: output atomic, same on every rank ----------------------------------------


def shared(tmp_path):
    from pathlib import Path

    return Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))


def test_command_writes_a_contract_directory(tmp_path):
    """import-dic writes experiment.toml + field.csv (+ dic_import.json) that load_experiment
    reads back to the imported field (1 and 2 ranks: the work is rank 0's, the exit status
    every rank's); with a bad input it exits 2 and writes nothing."""
    base = shared(tmp_path)
    if COMM.rank == 0:
        spec, _ = make(base, "dice", points=grid(spacing=2.0), noise=0.01)
        spec.write_text(
            spec.read_text().replace("[steps]", "[steps]\nforce = [1.0, 2.0, 2.5]")
            + "\n[binning]\npitch = 6.0\n"
        )
    COMM.barrier()
    out = base / "measured"
    assert main(["import-dic", str(base / "dic.toml"), "--out", str(out)]) == 0
    exp = load_experiment(out)
    ref, _rep = import_dic(read_spec(base / "dic.toml"))
    assert np.abs(exp.u - ref.u).max() < 1e-8 and list(exp.force) == [1.0, 2.0, 2.5]
    assert exp.noise_std == pytest.approx(ref.noise_std, rel=1e-8)
    assert (out / "dic_import.json").is_file()
    COMM.barrier()
    if COMM.rank == 0:
        spec = base / "dic.toml"
        spec.write_text(spec.read_text().replace("mm_per_pixel = 0.05", ""))
    COMM.barrier()
    bad = base / "bad"
    assert main(["import-dic", str(base / "dic.toml"), "--out", str(bad)]) == 2
    COMM.barrier()  # rank 0 removes the staging directory
    assert not bad.exists() and not list(base.glob(".bad.partial-*"))
