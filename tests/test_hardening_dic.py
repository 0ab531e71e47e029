"""Hardening of ``fabricsurf import-dic`` (issue 52, "real exports as labs write them"): each
input that was read wrongly without a word now ends, through the command line, with exit 2 on
every rank and one message naming the file, line or key, the value and the remedy, before
anything is written.

The rejected inputs (``CASES``, the format of tests/test_hardening.py) are meant for
docs/input_errors.md (benchmarks/regenerate_input_errors.py). numpy only: no FEniCSx solve.
"""

import re
from pathlib import Path

import pytest
import test_hardening as th
from mpi4py import MPI
from test_dic import grid, make, spec_text
from test_dic_layouts import MM, _recode

COMM = MPI.COMM_WORLD


def dic_case(name: str, layout="dice", frame=None, text=None, edit=None):
    """A synthetic export in ``base/name`` (4 mm grid, 3 images) changed by ``edit(d)``."""

    def build(base: Path) -> None:
        d = base / name
        kwargs = {} if frame is None else {"frame": frame}
        make(d, layout, points=grid(spacing=4.0), holes=0.0, text=text, **kwargs)
        if edit is not None:
            edit(d)

    return build


def argv(name: str) -> list[str]:
    return ["import-dic", f"{name}/dic.toml", "--out", "out"]


def extra_field(d: Path) -> None:
    f = d / "img" / "DICe_solution_02.txt"
    lines = f.read_text().splitlines()
    cells = lines[9].split(",")
    lines[9] = ",".join([*cells[:2], "12", "5", *cells[3:]])
    f.write_text("\n".join(lines) + "\n")


def ambiguous(d: Path) -> None:
    for f in (d / "img").iterdir():
        _recode(f, f, "cp1252", "– 5 %")


def negative_force(d: Path) -> None:
    spec = d / "dic.toml"
    spec.write_text(spec.read_text().replace("[steps]", "[steps]\nforce = [-8.0, -15.5, -23.0]"))


def tag_mismatch(d: Path) -> None:
    for f in (d / "img").iterdir():
        f.write_text(
            f.read_text().replace("x_undef [mm]", "X [mm]").replace("y_undef [mm]", "Y [mm]")
        )


COLUMNS_REF = (
    '[columns]\nx = "x"\ny = "y"\nu = "u"\nv = "v"\npixel_x = "x_pic"\n'
    'pixel_y = "y_pic"\ny_down = false\n'
)
TAGGED = '[columns]\nx = "X [m]"\ny = "Y [m]"\nu = "u"\nv = "v"\n'

CASES = [
    dict(
        id="dic-deformed-as-reference",
        klass="DIC export with deformed coordinates (MatchID) read as reference coordinates",
        make=dic_case(
            "deformed", "matchid", MM, text=spec_text("columns", frame=MM, extra=COLUMNS_REF)
        ),
        argv=argv("deformed"),
        pattern=r"export_002.csv: x of image 2 − x of image 1 \(export_001.csv\) equals u of "
        r"image 2 − u of image 1 .* on 100% of the \d+ points that moved, matched by "
        r"their integer pixel position: these are deformed coordinates .* set "
        r"\[columns\] coordinates = \"deformed\"",
    ),
    dict(
        id="dic-reference-as-deformed",
        klass="DIC export with reference coordinates declared deformed",
        make=dic_case(
            "refdef", text=spec_text().replace("[export]", '[export]\ncoordinates = "deformed"')
        ),
        argv=argv("refdef"),
        pattern=r"DICe_solution_02.txt: x of image 2 equals x of image 1 .* these are "
        r"reference coordinates, read as deformed ones; set \[export\] coordinates = "
        r"\"reference\"",
    ),
    dict(
        id="dic-extra-field",
        klass="DIC row with one field too many (decimal comma in a comma-separated file)",
        make=dic_case("extra", edit=extra_field),
        argv=argv("extra"),
        pattern=r"DICe_solution_02.txt line 10: 6 fields, the header \(line 6\) has 5; fields "
        r"3 and 4 read '12' and '5': a decimal comma \(12,5\)",
    ),
    dict(
        id="dic-encoding-ambiguous",
        klass="DIC export neither UTF-8 nor readable alike in "
        "Latin-1 and cp1252, no [export] encoding",
        make=dic_case("cp1252", "aramis_nodemap", MM, edit=ambiguous),
        argv=argv("cp1252"),
        pattern=r"nodemap_stage_0001.txt line 2: not UTF-8 .* byte 0x96 reads as '–' in "
        r"cp1252 but as the control character U\+0096 in latin-1: set \[export\] "
        r"encoding = \"cp1252\"",
    ),
    dict(
        id="dic-negative-force",
        klass="negative forces of a bias (tension) test",
        make=dic_case("negforce", edit=negative_force),
        argv=argv("negforce"),
        pattern=r"dic.toml: \[steps\] force: step 1 \(image 1\): force -8 N is negative \(3 of "
        r"3 steps are\); the 'bias_extension' test pulls the specimen .* flip the sign",
    ),
    dict(
        id="dic-unit-tag-mismatch",
        klass="`[columns]` name with a unit tag the file contradicts",
        make=dic_case(
            "tags",
            "aramis_nodemap",
            MM,
            text=spec_text("columns", frame=MM, extra=TAGGED),
            edit=tag_mismatch,
        ),
        argv=argv("tags"),
        pattern=r"nodemap_stage_0001.txt line 4: column 'X' is in \[mm\] but \[columns\] x = "
        r"\"X \[m\]\" says \[m\]",
    ),
]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return th.shared_root(tmp_path_factory, "harddic", CASES, good=False)


@pytest.fixture
def in_root(root, monkeypatch):
    monkeypatch.chdir(root)
    return root


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_rejected_before_anything_is_written(case, in_root, capsys):
    """Each input: exit 2 on every rank, one message, nothing written (the listing is taken
    on every rank before any rank starts the command, which takes its --out lock first)."""
    before = sorted(p.name for p in in_root.iterdir())
    COMM.barrier()
    rc, msg = th.run_cli(case["argv"], capsys)
    assert rc == 2, msg
    assert re.search(case["pattern"], msg), (case["pattern"], msg)
    assert len(msg.splitlines()) == 1, msg
    COMM.barrier()
    assert sorted(p.name for p in in_root.iterdir()) == before
