"""docs/dic.md, issue 52: exports as the programs write them. DICe's files as DICe writes
them (its header line and column names, MATCH = -1 with zero strains on lost subsets, a frame 0
correlated with itself to round-off, the stereo MODEL_* columns with SIGMA; written here by
fabricsurf.inverse.dic.export.write_dice_solution with known values) imported to those values;
the named layouts (MatchID's two header generations, DaVis) through the generator; deformed
coordinates converted exactly and refused with the measured evidence when declared otherwise; a
row with a field too many refused on the fast path; encodings read to the same arrays as UTF-8,
and refused when Latin-1 and cp1252 would read them differently. (Excerpts of DICe's own
regression files were checked by hand, not committed: docs/dic.md, Layouts.)"""

import re
from pathlib import Path

import numpy as np
import pytest
from test_dic import SERIAL, grid, linear, make, spec_text

from fabricsurf.errors import DataError
from fabricsurf.inverse.dic.description.spec import read_spec
from fabricsurf.inverse.dic.export import (
    DICE_2D,
    DICE_STEREO,
    dice_printed,
    write_dice_solution,
    write_images,
)
from fabricsurf.inverse.dic.frame import Frame
from fabricsurf.inverse.dic.importer import import_dic
from fabricsurf.inverse.dic.layouts import LAYOUTS

pytestmark = SERIAL
MM = Frame(1.0, False, (0.0, 0.0), "left", 0.0)


def reject(spec, *patterns):
    with pytest.raises(DataError) as e:
        import_dic(read_spec(spec))
    for p in patterns:
        assert re.search(p, str(e.value)), (p, str(e.value))
    return str(e.value)


def dice_spec(d, layout, frame, specimen, steps, extra=""):
    spec = d / "dic.toml"
    spec.write_text(f"""name = "dice-format"
[export]
layout = "{layout}"
files = "img/DICe_solution_*.txt"
{extra}
{frame}
[specimen]
{specimen}
fibre_angles_deg = [45.0, -45.0]
[loading]
test = "bias_extension"
[steps]
{steps}
""")
    return spec


# --- DICe's own format (dice: no SIGMA, MATCH; dice_stereo: MODEL_*, SIGMA) -----------------

PX = 0.05  # mm per pixel
ORIGIN = (2050.0, 1950.0)  # pixel of the specimen's origin; grip at the image bottom
LOST = ([3, 4, 40, 41], [4, 40, 41], [4, 40])  # MATCH = -1 rows of images 0, 1, 2
NOISE = 0.01  # mm (0.2 pixel) on images 1 and 2
DOGBONE = (
    f"[units]\nmm_per_pixel = {PX}\n[frame]\norigin = [{ORIGIN[0]}, {ORIGIN[1]}]\n"
    'grip = "bottom"\nangle_deg = 0.0',
    "length = 100.0\nwidth = 20.0",
    "reference_images = [0]\nimages = [1, 2]\npath = [1.0, 2.0]",
)


def dice_dogbone(d, seed=11):
    """DICe 2-D files (DICE_2D: no SIGMA) of a 100 × 20 mm gauge on a 1 mm grid (99 × 19 =
    1881 subsets) seen at 0.05 mm/pixel with the grip at the image bottom (y down: x = 2050 −
    20 Y, y = 1950 − 20 X pixel): image 0 correlated with itself, |u| < 2.7e-14 pixel; images
    1, 2 the field t·(0.3 + X/100, −0.01 (Y − 10)) mm, t = 1, 2, plus N(0, 0.01 mm) noise
    (the 0.3 t mm = 6 t pixel translation moves every point beyond the coordinate check's
    10 × 1e-4 × (|y| + |y'| + …) ≈ 3.9 pixel, 10σ of the noise clear); MATCH = −1 with zero
    strains on the LOST rows (their displacements kept, as DICe does). Returns the points and
    each image's displacements as printed, in mm in the specimen frame."""
    X = np.array([(a, b) for a in range(1, 100) for b in range(1, 20)], float)
    n = len(X)
    rng = np.random.default_rng(seed)
    Us = []
    for k, t in enumerate((0.0, 1.0, 2.0)):
        if k == 0:
            D = rng.uniform(-2.7e-14, 2.7e-14, (n, 2))
        else:
            U = t * np.column_stack([0.3 + X[:, 0] / 100, -0.01 * (X[:, 1] - 10)])
            U += rng.normal(0.0, NOISE, X.shape)
            D = np.column_stack([-U[:, 1], -U[:, 0]]) / PX
        D = dice_printed(D)
        lost = np.isin(np.arange(n), LOST[k])
        strain = np.where(lost, 0.0, 0.01 * t)
        write_dice_solution(
            d / "img" / f"DICe_solution_{k}.txt",
            DICE_2D,
            {
                "COORDINATE_X": ORIGIN[0] - X[:, 1] / PX,
                "COORDINATE_Y": ORIGIN[1] - X[:, 0] / PX,
                "CROSS_CORR_Q": np.full(n, 52.314),
                "CROSS_CORR_R": np.full(n, -33.0),
                "DISPLACEMENT_X": D[:, 0],
                "DISPLACEMENT_Y": D[:, 1],
                "VSG_STRAIN_YY": strain,
                "NLVC_STRAIN_YY": strain,
                "GAMMA": np.full(n, 7e-3 if k else 5e-28),
                "MATCH": np.where(lost, -1.0, 0.0),
            },
        )
        Us.append(np.column_stack([-PX * D[:, 1], -PX * D[:, 0]]))
    return X, Us


def test_dice_match_flag_and_roundoff_reference(tmp_path):
    """DICe's 2-D files (header line and columns as DICe writes them, no SIGMA): the MATCH = −1
    rows are dropped and counted (4, 3, 2 written: exactly those), the round-off image 0 gives no
    noise and is said to; the noise is estimated from the steps instead, 0.01 mm within 6 % (over
    200 seeds the estimate is 0.995 ± 0.011 of it, range 0.960–1.027: 6 % is the bias + 5σ); the
    field is the printed DISPLACEMENT
    columns turned to the specimen's frame (X = −0.05 v, Y = −0.05 u) to round-off, at the
    written points."""
    X, Us = dice_dogbone(tmp_path)
    head = (tmp_path / "img" / "DICe_solution_1.txt").read_text().splitlines()[0]
    assert head.split(",") == list(DICE_2D) and "SIGMA" not in head
    spec = dice_spec(tmp_path, "dice", *DOGBONE)
    exp, rep = import_dic(read_spec(spec))
    assert [e["holes"] for e in rep["reference"] + rep["files"]] == [4, 3, 2]
    assert [e["points"] for e in rep["reference"] + rep["files"]] == [1877, 1878, 1879]
    assert rep["noise"]["roundoff_reference_images"] == [0]
    assert rep["noise"]["method"].startswith(
        "estimated: local plane residuals of the written "
        "field, all steps; reference image(s) [0] hold "
        "round-off displacements only"
    )
    assert exp.noise_std == pytest.approx(NOISE, rel=0.06)
    for s in (1, 2):
        keep = ~np.isin(np.arange(len(X)), LOST[s])
        rows = exp.step_rows(s)
        assert len(rows) == keep.sum()
        assert np.abs(exp.X[rows] - X[keep]).max() < 1e-12
        assert np.abs(exp.u[rows] - Us[s][keep]).max() < 1e-14
    ev = rep["coordinates"]["evidence"]
    assert [(e["image"], e["matched"], e["moved"]) for e in ev] == [
        (1, 1877, 1877),
        (2, 1877, 1877),
    ]
    assert all(e["checked"] and e["stay"] == 1.0 for e in ev)


def test_dice_reference_coordinates_declared_deformed(tmp_path):
    """The same files declared deformed: x of image 1 equals x of image 0 on every one of the
    1881 − 4 points valid in both (all moved), so the import is refused with that evidence."""
    dice_dogbone(tmp_path)
    spec = dice_spec(tmp_path, "dice", *DOGBONE, extra='coordinates = "deformed"')
    reject(
        spec,
        r"DICe_solution_1.txt: x of image 1 equals x of image 0 .* on 100% of the "
        r"1877 points whose displacement changed, matched by row .* these are reference "
        r"coordinates, read as deformed ones; set \[export\] coordinates = \"reference\"",
    )


def test_dice_stereo_model_columns(tmp_path):
    """DICe's stereo files (DICE_STEREO: MODEL_* columns in mm, MODEL_COORDINATES_Y growing with
    COORDINATE_Y as in DICe's files, i.e. y down like the image; SIGMA): read as mm with y
    flipped, SIGMA = −1 rows dropped and counted, the planar test's MODEL_DISPLACEMENT_Z
    recorded as dropped, the field the printed MODEL_DISPLACEMENT columns turned (grip at the
    bottom: X = 2.8 − y, Y = 0.75 − x, U = (−v, −u))."""
    cx, cy = (
        a.ravel()
        for a in np.meshgrid(np.arange(500.0, 701.0, 25.0), np.arange(100.0, 1001.0, 25.0))
    )
    n = len(cx)
    M = dice_printed(
        np.column_stack([0.0056 * (cx - 600), 0.0056 * (cy - 550), -0.03 + 1e-5 * (cx - 600)])
    )
    X = np.column_stack([2.8 - M[:, 1], 0.75 - M[:, 0]])
    rng = np.random.default_rng(2)
    lost = [[], [5, 77]]
    for k, t in enumerate((0.0, 1.0)):
        U = t * np.column_stack([0.01 * X[:, 0], -0.002 * (X[:, 1] - 0.75)])
        MD = dice_printed(
            np.column_stack([-U[:, 1], -U[:, 0], np.full(n, 0.03 * t)])
            + rng.normal(0.0, 3e-8, (n, 3))
        )
        write_dice_solution(
            tmp_path / "img" / f"DICe_solution_{k}.txt",
            DICE_STEREO,
            {
                "COORDINATE_X": cx,
                "COORDINATE_Y": cy,
                "DISPLACEMENT_X": MD[:, 0] / 0.0056,
                "DISPLACEMENT_Y": MD[:, 1] / 0.0056,
                "MODEL_COORDINATES_X": M[:, 0],
                "MODEL_COORDINATES_Y": M[:, 1],
                "MODEL_COORDINATES_Z": M[:, 2],
                "MODEL_DISPLACEMENT_X": MD[:, 0],
                "MODEL_DISPLACEMENT_Y": MD[:, 1],
                "MODEL_DISPLACEMENT_Z": MD[:, 2],
                "SIGMA": np.where(np.isin(np.arange(n), lost[k]), -1.0, 0.004),
            },
        )
    spec = dice_spec(
        tmp_path,
        "dice_stereo",
        '[frame]\norigin = [0.75, 2.8]\ngrip = "bottom"\nangle_deg = 0.0',
        "length = 6.0\nwidth = 1.5",
        "images = [0, 1]\npath = [0.0, 1.0]",
    )
    exp, rep = import_dic(read_spec(spec))
    assert rep["unit"] == "mm"
    assert rep["dropped_columns"] == {
        "w": "planar test: the out-of-plane displacement column 'MODEL_DISPLACEMENT_Z' is not used"
    }
    assert [e["holes"] for e in rep["files"]] == [0, 2]
    keep = ~np.isin(np.arange(n), lost[1])
    rows = exp.step_rows(2)
    assert len(rows) == n - 2 == 331
    assert np.abs(exp.X[rows] - X[keep]).max() < 1e-12
    assert np.abs(exp.u[rows, 0] + MD[keep, 1]).max() < 1e-15
    assert np.abs(exp.u[rows, 1] + MD[keep, 0]).max() < 1e-15


# --- deformed coordinates ------------------------------------------------------------------


def exact_field(X, t):
    """Displacements that are multiples of 1/64 mm: X + u is exact in binary and in print."""
    return np.column_stack(
        [np.round(64 * t * X[:, 0] / 120) / 64, np.round(-64 * 0.1 * t * X[:, 1] / 80) / 64]
    )


def test_matchid_deformed_coordinates_recover_the_grid(tmp_path):
    """MatchID's export (x_pic, y_pic, x, y, u, v: x the deformed position) on an integer mm
    grid with dyadic displacements: reference = deformed − displacement gives back the grid
    exactly (1e-12), every step; both header generations import to the same field."""
    X = grid(spacing=2.0)
    spec, _ = make(tmp_path, "matchid", MM, field=exact_field, points=X, holes=0.03)
    exp, rep = import_dic(read_spec(spec))
    assert rep["coordinates"]["converted"] and all(
        e["checked"] and e["move_with_displacement"] == 1.0 for e in rep["coordinates"]["evidence"]
    )
    for s, t in zip(exp.steps, exp.path):
        rows = exp.step_rows(s)
        ref = {tuple(p) for p in X}
        assert all(tuple(p) in ref for p in exp.X[rows])  # exact grid points
        assert np.abs(exp.u[rows] - exact_field(exp.X[rows], t)).max() < 1e-12
    new = {
        "x_pic": "Coordinates.Image X [Pixel]",
        "y_pic": "Coordinates.Image Y [Pixel]",
        "x": "coor.X [mm]",
        "y": "coor.Y [mm]",
        "u": "disp.Horizontal Displacement U [mm]",
        "v": "disp.Vertical Displacement V [mm]",
    }
    for f in (tmp_path / "img").iterdir():
        lines = f.read_text().splitlines()
        lines[0] = ",".join(new[c] for c in lines[0].split(","))
        f.write_text("\n".join(lines) + "\n")
    exp2, _ = import_dic(read_spec(spec))
    assert np.array_equal(exp2.u, exp.u) and np.array_equal(exp2.X, exp.X)


def test_deformed_coordinates_declared_reference_are_refused(tmp_path):
    """A MatchID-like export read through [columns] as reference coordinates: x of image 2 − x
    of image 1 equals u of image 2 − u of image 1 on every point that moved; refused with that
    evidence and the key; with coordinates = "deformed" it imports the generator's field."""
    cols = (
        '[columns]\nx = "x"\ny = "y"\nu = "u"\nv = "v"\npixel_x = "x_pic"\n'
        'pixel_y = "y_pic"\ny_down = false\n'
    )
    spec, _ = make(
        tmp_path, "matchid", MM, holes=0.02, text=spec_text("columns", frame=MM, extra=cols)
    )
    reject(
        spec,
        r"export_002.csv: x of image 2 − x of image 1 \(export_001.csv\) equals u of "
        r"image 2 − u of image 1 .* on 100% of the \d+ points that moved, matched by their "
        r"integer pixel position: these are deformed coordinates .* set \[columns\] "
        r"coordinates = \"deformed\"",
    )
    spec.write_text(spec.read_text() + 'coordinates = "deformed"\n')
    exp, _ = import_dic(read_spec(spec))
    err = max(
        np.abs(exp.u[exp.step_rows(s)] - linear(exp.X[exp.step_rows(s)], t)).max()
        for s, t in zip(exp.steps, exp.path)
    )
    assert err < 1e-6


def test_davis_zero_rows_and_quoted_header(tmp_path):
    """DaVis: the '#DaVis 10.x …' line with quoted, tagged names and ';', deformed
    coordinates, lost points written as zeros with isValid = 0: 5 % of the points dropped and
    counted, the field the generator's."""
    spec, _ = make(tmp_path, "davis", MM, holes=0.05)
    exp, rep = import_dic(read_spec(spec))
    first = (tmp_path / "img" / "export_001.csv").read_text().splitlines()[0]
    assert first.startswith("#DaVis 10.x 2C vector field") and '"Vx [mm]"' in first
    text = (tmp_path / "img" / "export_001.csv").read_text()
    rows = [r.split(";") for r in text.splitlines()[1:]]
    assert rep["files"][0]["holes"] == sum(float(r[-1]) == 0 for r in rows) > 0
    err = max(
        np.abs(exp.u[exp.step_rows(s)] - linear(exp.X[exp.step_rows(s)], t)).max()
        for s, t in zip(exp.steps, exp.path)
    )
    assert err < 1e-6


# --- [columns] with unit tags; w dropped -------------------------------------------------


def test_columns_names_with_unit_tags(tmp_path):
    """[columns] x = "X [mm]" (docs/dic.md's own example) reads a header "X [mm]"; a tag that
    disagrees with the file's is refused naming both."""
    extra = '[columns]\nx = "X [mm]"\ny = "Y [mm]"\nu = "U [mm]"\nv = "V [mm]"\n'
    spec, _ = make(
        tmp_path,
        LAYOUTS["aramis_nodemap"],
        MM,
        holes=0.0,
        text=spec_text("columns", frame=MM, extra=extra),
    )
    for f in (tmp_path / "img").iterdir():
        f.write_text(
            f.read_text()
            .replace("x_undef [mm]", "X [mm]")
            .replace("y_undef [mm]", "Y [mm]")
            .replace("; u [mm]", "; U [mm]")
            .replace("; v [mm]", "; V [mm]")
        )
    exp, _ = import_dic(read_spec(spec))
    assert len(exp.X) == 3 * len(grid())
    spec.write_text(spec.read_text().replace('u = "U [mm]"', 'u = "U [m]"'))
    reject(
        spec,
        r"nodemap_stage_0001.txt line 4: column 'U' is in \[mm\] but \[columns\] u = "
        r"\"U \[m\]\" says \[m\]",
    )


def test_planar_test_records_the_dropped_w(tmp_path):
    """A w column on a planar test is not used: dic_import.json says so."""
    X = grid(spacing=4.0)
    Us = [linear(X, t) for t in (2.0, 4.0, 6.0)]
    write_images(
        tmp_path / "img", LAYOUTS["vic3d"], MM, [1, 2, 3], X, Us, w=[0.01 * np.ones(len(X))] * 3
    )
    spec = tmp_path / "dic.toml"
    spec.write_text(spec_text("vic3d", frame=MM))
    _, rep = import_dic(read_spec(spec))
    assert rep["dropped_columns"] == {
        "w": "planar test: the out-of-plane displacement column 'W' is not used"
    }


# --- field counts on the fast path -----------------------------------------------------------


def test_extra_field_refused_on_the_fast_path(tmp_path):
    """One field too many (a decimal comma in a comma-separated file) on a row the fast
    reader would read shifted without a word: refused with the line, the counts and the
    hint; a row with one too few likewise; rows that all end with a delimiter still import."""
    spec, _ = make(tmp_path, "dice", points=grid(spacing=4.0), holes=0.0)
    f = tmp_path / "img" / "DICe_solution_02.txt"
    lines = f.read_text().splitlines()
    head = next(k for k, r in enumerate(lines, 1) if r.startswith("COORD"))
    cells = lines[head + 3].split(",")
    lines[head + 3] = ",".join([*cells[:2], "12", "5", *cells[3:]])
    f.write_text("\n".join(lines) + "\n")
    reject(
        spec,
        rf"DICe_solution_02.txt line {head + 4}: 6 fields, the header \(line {head}\) "
        r"has 5; fields 3 and 4 read '12' and '5': a decimal comma \(12,5\)",
    )


# --- encodings -------------------------------------------------------------------------------


def _recode(src: Path, dst: Path, codec: str, mark: str, bom: bytes = b"") -> None:
    text = src.read_text()
    lines = text.splitlines()
    lines.insert(1, f"# operator note: strain {mark}")  # a non-ASCII preamble line
    dst.write_bytes(bom + ("\r\n".join(lines) + "\r\n").encode(codec))


@pytest.mark.parametrize(
    "codec,mark,bom,key,label",
    [
        ("utf-8", "°", b"\xef\xbb\xbf", None, "utf-8 (with BOM)"),
        ("utf-16-le", "°", b"\xff\xfe", None, "utf-16-le (with BOM)"),
        ("utf-16-be", "mm²", b"\xfe\xff", None, "utf-16-be (with BOM)"),
        ("latin-1", "°", b"", None, "latin-1/cp1252 (same text)"),
        ("cp1252", "mm²", b"", None, "latin-1/cp1252 (same text)"),
        ("cp1252", "– ‰", b"", "cp1252", "cp1252"),
    ],
)
def test_encodings_read_the_same_arrays(tmp_path, codec, mark, bom, key, label):
    """The nodemap written in each encoding (DaVis's Latin-1 °, a Windows exporter's cp1252
    mm² and en dash, UTF-16 from Windows tools) imports to the same arrays as the UTF-8 file,
    and dic_import.json records the encoding."""
    spec, _ = make(tmp_path, "aramis_nodemap", MM, points=grid(spacing=4.0), holes=0.02)
    ref, _ = import_dic(read_spec(spec))
    for f in sorted((tmp_path / "img").iterdir()):
        _recode(f, f, codec, mark, bom)
    if key:
        spec.write_text(spec.read_text().replace("[export]", f'[export]\nencoding = "{key}"'))
    exp, rep = import_dic(read_spec(spec))
    assert rep["encoding"] == [label]
    assert np.array_equal(exp.u, ref.u) and np.array_equal(exp.X, ref.X)


def test_ambiguous_single_byte_encoding_is_refused(tmp_path):
    """Bytes 0x80–0x9F read differently in cp1252 and Latin-1: without the key the import
    names the byte, the line and both readings."""
    spec, _ = make(tmp_path, "aramis_nodemap", MM, points=grid(spacing=4.0), holes=0.0)
    f = sorted((tmp_path / "img").iterdir())[0]
    _recode(f, f, "cp1252", "– 5 %")
    reject(
        spec,
        rf"{f.name} line 2: not UTF-8 .* byte 0x96 reads as '–' in cp1252 but as the "
        r"control character U\+0096 in latin-1: set \[export\] encoding = \"cp1252\"",
    )


def test_absolute_file_pattern(tmp_path):
    """[export] files as an absolute glob is read (glob.glob), like the relative one."""
    spec, _ = make(tmp_path, "dice", points=grid(spacing=4.0))
    ref, _ = import_dic(read_spec(spec))
    spec.write_text(
        spec.read_text().replace('files = "img/*"', f'files = "{tmp_path}/img/DICe_solution_*.txt"')
    )
    exp, _ = import_dic(read_spec(spec))
    assert np.array_equal(exp.u, ref.u)


def test_negative_bias_forces(tmp_path):
    """Negative forces of a bias test beyond 3 % of the largest |force| are refused with the
    step, the image and the value; a load cell's zero offset at the first step is not."""
    spec, _ = make(tmp_path, "dice", points=grid(spacing=4.0))
    text = spec.read_text()
    spec.write_text(text.replace("[steps]", "[steps]\nforce = [-8.0, -15.5, -23.0]"))
    with pytest.raises(
        DataError,
        match=r"dic.toml: \[steps\] force: step 1 \(image 1\): force "
        r"-8 N is negative \(3 of 3 steps are\); the 'bias_extension' test "
        r"pulls the specimen",
    ):
        read_spec(spec)
    spec.write_text(text.replace("[steps]", "[steps]\nforce = [-0.2, 15.5, 23.0]"))
    assert read_spec(spec).force == [-0.2, 15.5, 23.0]


def test_field_count_on_bytes():
    """The byte-level count: blank and comment lines are not data, a delimiter-separated row
    of one field more or less is caught, blank-separated columns count words, and UTF-16 code
    units count like bytes."""
    from fabricsurf.inverse.dic.encoding import Encoding
    from fabricsurf.inverse.dic.fields import fields_agree

    utf8 = Encoding("utf-8-sig", "utf-8")
    text = "# pre\nx,y,u\n1,2,3\n\n# note\n4,5,6\n"
    assert fields_agree(text.encode(), utf8, 2, ",", 3)
    assert not fields_agree(text.replace("4,5,6", "4,5,6,7").encode(), utf8, 2, ",", 3)
    assert not fields_agree(text.replace("4,5,6", "4,5").encode(), utf8, 2, ",", 3)
    blanks = "x y u\n 1  2\t3\n4 5 6 \n"
    assert fields_agree(blanks.encode(), utf8, 1, None, 3)
    assert not fields_agree(blanks.replace("4 5 6", "4 5 6 7").encode(), utf8, 1, None, 3)
    le = Encoding("utf-16", "utf-16-le", 2, 2, False)
    assert fields_agree(b"\xff\xfe" + text.encode("utf-16-le"), le, 2, ",", 3)
    assert not fields_agree(
        b"\xff\xfe" + text.replace("1,2,3", "1,2,3,9").encode("utf-16-le"), le, 2, ",", 3
    )


def test_roundoff_reference_image_gives_no_noise(tmp_path):
    """A DaVis reference image whose displacements are round-off (±8.4e-13 mm): not a noise
    image; the noise (σ = 0.01 mm drawn on the quadratic steps) is estimated from the steps
    instead, within 10 %, and the method says why (it was "no scatter" and 1 % of the largest
    displacement before)."""
    X = grid(spacing=2.0)
    rng = np.random.default_rng(5)
    quad = np.column_stack([(X[:, 0] / 120) ** 2, 0 * X[:, 1]])
    Us = [8.4e-13 * np.sign(rng.normal(size=X.shape))] + [
        t * quad + rng.normal(0, 0.01, X.shape) for t in (2.0, 4.0, 6.0)
    ]
    write_images(tmp_path / "img", LAYOUTS["davis"], MM, [0, 1, 2, 3], X, Us)
    spec = tmp_path / "dic.toml"
    spec.write_text(
        spec_text(
            "davis",
            frame=MM,
            steps="reference_images = [0]\nimages = [1, 2, 3]\npath = [2.0, 4.0, 6.0]",
        )
    )
    exp, rep = import_dic(read_spec(spec))
    assert rep["noise"]["roundoff_reference_images"] == [0]
    assert rep["noise"]["method"].startswith(
        "estimated: local plane residuals of the written "
        "field, all steps; reference image(s) [0] hold "
        "round-off displacements only"
    )
    assert exp.noise_std == pytest.approx(0.01, rel=0.1)
