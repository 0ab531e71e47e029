"""Hardening, third round (issue 41): size guards on default element sizes, data the
comparison cannot use refused by name, encodings and special files, TOML arrays, and the
output directory as one run's property: a lock against a concurrent run, no stale results of an
earlier run beside new ones, no stale staging directory, names of any valid length, no empty
OUT after a failure, per-point files in the units their columns name.

The rejected inputs here (``CASES``) join those of the other hardening tests in
docs/input_errors.md; the test that the table is up to date lives here and covers every list
(benchmarks/regenerate_input_errors.py, ``all_cases``).
No FEniCSx solve: every case is refused before any computation, the rest is file handling.
"""

import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import test_hardening as th
from mpi4py import MPI
from regenerate_input_errors import all_cases, case_env, errors_table, table_row

import fabricsurf.cli as cli
import fabricsurf.cli.measure as measure_cli
from fabricsurf.cli.outdir import MANIFEST, OutputDir
from fabricsurf.discretise.output import write_json
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.data import load_experiment, write_experiment
from fabricsurf.inverse.plots.outputs import _per_point, slug

COMM = MPI.COMM_WORLD
TERMS = th.TERMS
DOC = th.DOC


def toml_edits(*pairs):
    """An edit of experiment.toml replacing each (old, new) once; old must be there."""
    return th.edits(*(th.replace("experiment.toml", a, b) for a, b in pairs))


def force_only(d: Path) -> None:
    """The force alone: the field, its file and its noise level removed."""
    toml_edits(('field = "field.csv"\n', ""), ("\nnoise_std = 0.01\n", "\n"))(d)
    (d / "field.csv").unlink()


def with_uz(d: Path) -> None:
    """field.csv with a third displacement column (out-of-plane data)."""
    rows = (d / "field.csv").read_text().splitlines()
    (d / "field.csv").write_text(
        "\n".join([rows[0] + ",uz"] + [r + ",-0.5" for r in rows[1:] if r]) + "\n"
    )


def utf16_without_bom(d: Path) -> None:
    (d / "field.csv").write_bytes((d / "field.csv").read_text().encode("utf-16-le"))


def fifo(d: Path) -> None:
    (d / "force.csv").unlink()
    os.mkfifo(d / "force.csv")


CASES = [
    dict(
        id="compare-default-h-too-fine",
        klass="`compare` of a 3000 × 1 mm specimen without "
        "`--h` (the default element size, min(length, width)/10, is checked as a given one)",
        make=th.variant(
            "long",
            th.edits(
                force_only,
                toml_edits(("length = 40.0", "length = 3000.0"), ("width = 20.0", "width = 1.0")),
            ),
        ),
        argv=th.cmp("long"),
        pattern=r"no --h given: the tests' default element sizes \('"
        r"synthetic' 3000 x 1 mm at h = 0.1 mm\) give about 600,000 elements, more than "
        r"--max-elements 400,000",
    ),
    dict(
        id="fit-h-half-too-fine",
        klass="`fit` whose mesh check at h/2 would exceed "
        "`--max-elements` (the guard counts the finest mesh a command builds)",
        make=th.nothing,
        argv=[
            "fit",
            "good",
            "--terms",
            TERMS,
            "--h",
            "1",
            "--max-elements",
            "3000",
            "--out",
            "out",
        ],
        pattern=r"--h 1: about 6,400 elements \('synthetic' 40 x 20 mm; at h/2 = "
        r"0.5 mm \(fit and diagnose also solve there: the mesh check\)\), more than "
        r"--max-elements 3,000",
    ),
    dict(
        id="compare-hemisphere-field",
        klass='`compare` of a `test = "hemisphere"` '
        "directory with a displacement field (a formed part's field is not yet in the loop; "
        "its force and shear angles are)",
        make=th.variant(
            "dome",
            th.edits(
                with_uz,
                toml_edits(
                    ("width = 20.0", "width = 40.0"),
                    (
                        'test = "bias_extension"\nclamp = "gradient"',
                        'test = "hemisphere"\n[tooling]\npunch_radius = 5.0',
                    ),
                ),
            ),
        ),
        argv=th.cmp("dome"),
        pattern=r"dome/experiment.toml: \[data\] field with \[loading\] "
        r"test = \"hemisphere\": a displacement field of a formed part is not yet compared",
    ),
    dict(
        id="twist-planar",
        klass="twist or normal bending in `--terms` with planar data",
        make=th.nothing,
        argv=["fit", "good", "--terms", TERMS + ",twist", "--out", "out"],
        pattern=r"--terms fibre_stretch,shear,twist: twist is an out-of-plane effect, and "
        r"experiment 'synthetic' \(test 'bias_extension'\) is planar",
    ),
    dict(
        id="cantilever-no-bending",
        klass="cantilever data with planar terms only (no bending stiffness)",
        make=th.variant("cantflat", th.edits(th.cantilever("[0.5, 1.0]"), with_uz)),
        argv=["compare", "cantflat", "--terms", TERMS, "--out", "out"],
        pattern=r"--terms fibre_stretch,shear: experiment 'synthetic' is a cantilever, and no "
        r"term has a second gradient",
    ),
    dict(
        id="diagnose-mixed-candidates",
        klass="`diagnose` of planar and cantilever data "
        "together, default candidates (they include twist and normal bending)",
        make=th.variant(
            "strip",
            th.edits(
                th.cantilever("[0.5, 1.0]"),
                with_uz,
                toml_edits(('name = "synthetic"', 'name = "strip"')),
            ),
        ),
        argv=["diagnose", "good", "strip", "--terms", TERMS + ",geodesic_bending", "--out", "out"],
        pattern=r"no --candidates given: the default candidates include: "
        r"normal_bending, twist cannot be tried on planar experiment",
    ),
    dict(
        id="toml-string-angle",
        klass="a string where a number belongs in a TOML array (fibre angles)",
        make=th.variant("strangle", toml_edits(("[45.0, -45.0]", "['45', -45.0]"))),
        argv=th.cmp("strangle"),
        pattern=r"experiment.toml: \[specimen\] fibre_angles_deg\[0\] = "
        r"'45' must be a finite number \(written without quotes\)",
    ),
    dict(
        id="toml-string-path",
        klass="a string where a number belongs in a TOML array (load path)",
        make=th.variant("strpath", th.edits(th.cantilever('[0.5, "1"]'), with_uz)),
        argv=["compare", "strpath", "--terms", TERMS + ",normal_bending", "--out", "out"],
        pattern=r"experiment.toml: \[loading\] path\[1\] = '1' must be a finite number",
    ),
    dict(
        id="utf16-no-bom",
        klass="a CSV in UTF-16 without its byte-order mark (NUL bytes)",
        make=th.variant("utf16", utf16_without_bom),
        argv=th.cmp("utf16"),
        pattern=r"field.csv line 1: NUL bytes \(UTF-16 without its byte-order mark\?\): save "
        "the file as UTF-8",
    ),
    dict(
        id="fifo",
        klass="force.csv a named pipe (FIFO)",
        make=th.variant("fifo", fifo),
        argv=th.cmp("fifo"),
        pattern=r"force.csv: a named pipe \(FIFO\), not a regular file",
    ),
    dict(
        id="data-file-number",
        klass="`[data] field = 5` (a number where a file name belongs)",
        make=th.variant("fieldnum", toml_edits(('field = "field.csv"', "field = 5"))),
        argv=th.cmp("fieldnum"),
        pattern=r"experiment.toml: \[data\] field = 5 must be a file "
        r"name in quotes",
    ),
    dict(
        id="params-fifo",
        klass="`--params` a named pipe (FIFO; reading it would block)",
        make=lambda base: os.mkfifo(base / "pipe.json"),
        argv=th.cmp("good", "--params", "pipe.json"),
        pattern=r"--params pipe.json: a named pipe \(FIFO\), not a regular file",
    ),
    dict(
        id="out-root",
        klass="`--out /` (the results would be spread over the root)",
        make=th.nothing,
        argv=["bias", "--out", "/"],
        pattern=r"--out /: the root of the file system",
    ),
    dict(
        id="bias-width-gt-length",
        klass="`bias --width` larger than `--length`",
        make=th.nothing,
        argv=["bias", "--width", "150", "--length", "100", "--out", "out"],
        pattern=r"--width 150 exceeds --length 100: the bias specimen has its long side along "
        r"the load \(x\); swap them",
    ),
    dict(
        id="h-denormal",
        klass="`--h` so small the element count overflows (5e-324)",
        make=th.nothing,
        argv=th.cmp("good", "--h", "5e-324"),
        pattern=r"--h 4.94066e-324: far too small an element size for 'synthetic' 40 x 20 mm "
        r"\(the element count overflows\); give a larger --h",
    ),
    dict(
        id="bias-length-inf",
        klass="`bias --length inf`",
        make=th.nothing,
        argv=["bias", "--length", "inf", "--out", "out"],
        pattern=r"--length inf: must be a finite number \(mm\)",
    ),
]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """The inputs of every hardening module's cases (the table of docs/input_errors.md) in
    one directory shared by all ranks."""
    return th.shared_root(tmp_path_factory, "hard3", all_cases())


@pytest.fixture
def in_root(root, monkeypatch):
    monkeypatch.chdir(root)
    return root


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_rejected_before_any_solve(case, in_root, capsys, monkeypatch):
    """Each input: exit 2 on every rank, one message naming the option, key or file, nothing
    built or written (the element-count guard, the test, the terms, the encoding are checked
    before meshing; without these checks each of them ends in a traceback, a MemoryError or a
    wrong result)."""
    msg = th.rejected_message(case, in_root, capsys, monkeypatch)
    assert len(msg.splitlines()) == 1 and "\0" not in msg, msg


def test_errors_table_is_up_to_date(in_root, capsys):
    """docs/input_errors.md holds, row by row, the real messages of today's code for the cases
    of both files (``python benchmarks/regenerate_input_errors.py`` rewrites it)."""
    rows = []
    for c in all_cases():
        with case_env(c):
            rc, msg = th.run_cli(c["argv"], capsys)
        assert rc == 2, (c["id"], msg)
        rows.append(table_row(c, msg))
    assert DOC.read_text() == errors_table(rows), (
        "docs/input_errors.md is stale: run python benchmarks/regenerate_input_errors.py"
    )


# -- one output directory, one run ---------------------------------------------------------
def shared(tmp_path) -> Path:
    return Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))


def listing(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir())


def test_concurrent_run_refused(tmp_path):
    """While a run holds OUT, a second one is refused before it computes, naming the holder
    (its PID); once the first has published, OUT is free again and no lock file is left."""
    base = shared(tmp_path)
    first = OutputDir(base / "D", COMM)
    holder = COMM.bcast(os.getpid())  # rank 0 checks --out and holds the lock
    with pytest.raises(
        InputError,
        match=rf"--out {re.escape(str(base / 'D'))}: another "
        rf"fabricsurf run \(PID {holder} on .+\) is writing to this directory",
    ):
        OutputDir(base / "D", COMM)
    with first as stage:
        write_json(COMM, stage / "a.json", {})
    with OutputDir(base / "D", COMM) as stage:
        write_json(COMM, stage / "a.json", {"again": 1})
    COMM.barrier()
    assert listing(base) == ["D"]


def test_killed_run_leaves_nothing_the_next_run_keeps(tmp_path):
    """A run killed (SIGKILL) leaves its lock file, unlocked, and its staging directory: the
    next run into the same OUT takes the lock over and removes the stale staging directory
    (empty or not); another OUT's staging directories are not touched."""
    base = shared(tmp_path)
    if COMM.rank == 0:
        (base / ".D.lock").write_text("PID 999999 on elsewhere")
        (base / ".D.partial-dead1").mkdir()
        (base / ".D.partial-dead2").mkdir()
        (base / ".D.partial-dead2" / "bias.h5").write_bytes(b"cut")
        (base / ".E.partial-live").mkdir()
    COMM.barrier()
    with OutputDir(base / "D", COMM) as stage:
        write_json(COMM, stage / "a.json", {})
    COMM.barrier()
    assert listing(base) == [".E.partial-live", "D"]


def test_previous_results_replaced_as_a_whole(tmp_path):
    """A run into an OUT that holds another run's results: files of the earlier run the new
    one does not write (failure.json, per_point.csv …) are removed, files of the same name
    replaced, files no run wrote (the user's) kept; the record lists the new run's files."""
    base = shared(tmp_path)
    out = base / "D"
    with OutputDir(out, COMM) as stage:
        for name in ("fit.json", "failure.json", "per_point.csv", "misfit.json"):
            write_json(COMM, stage / name, {"run": 1})
    if COMM.rank == 0:
        (out / "notes.txt").write_text("mine")
    COMM.barrier()
    with OutputDir(out, COMM) as stage:
        write_json(COMM, stage / "misfit.json", {"run": 2})
        write_json(COMM, stage / "error_map.png", {"run": 2})
    COMM.barrier()
    assert listing(out) == [MANIFEST, "error_map.png", "misfit.json", "notes.txt"]
    assert json.loads((out / "misfit.json").read_text()) == {"run": 2}
    assert json.loads((out / MANIFEST).read_text())["files"] == ["error_map.png", "misfit.json"]


def test_record_cannot_remove_files_outside_out(tmp_path):
    """The record is data, not an instruction: names that lead out of OUT are ignored."""
    base = shared(tmp_path)
    out = base / "D"
    if COMM.rank == 0:
        out.mkdir()
        (base / "precious.txt").write_text("keep")
        (out / MANIFEST).write_text(json.dumps({"files": ["../precious.txt", "/etc/hostname"]}))
    COMM.barrier()
    with OutputDir(out, COMM) as stage:
        write_json(COMM, stage / "a.json", {})
    COMM.barrier()
    assert (base / "precious.txt").read_text() == "keep"


def test_longest_valid_out_name(tmp_path):
    """A 250-byte --out name (NAME_MAX is 255): the lock and staging names beside it are
    shortened with a hash, and the results are published under the name given."""
    base = shared(tmp_path)
    name = "r" * 241 + "-résumé"  # 250 bytes in UTF-8
    assert len(name.encode()) == 250
    with OutputDir(base / name, COMM) as stage:
        assert len(stage.name.encode()) < 100
        write_json(COMM, stage / "a.json", {})
    COMM.barrier()
    assert listing(base) == [name] and (base / name / "a.json").is_file()


def test_empty_out_refused(tmp_path, monkeypatch, capsys):
    """``--out ""`` (an unset shell variable) would publish into the working directory: it is
    a usage error."""
    monkeypatch.chdir(shared(tmp_path))
    rc, msg = th.run_cli(
        ["bias", "--length", "40", "--width", "20", "--h", "10", "--out", ""], capsys
    )
    assert rc == 2 and msg.splitlines()[-1] == (
        "fabricsurf bias: error: argument --out: '' is empty (an unset variable?); give the "
        "output directory by name"
    )
    assert listing(Path.cwd()) == []


def test_failure_before_writing_publishes_no_empty_out(tmp_path):
    """keep_on_error (bias) publishes what a failed run wrote; a failure before anything was
    written (e.g. in the mesh generator) leaves no empty OUT behind."""
    base = shared(tmp_path)
    with pytest.raises(ValueError, match="geometry"):
        with OutputDir(base / "D", COMM, keep_on_error=True):
            raise ValueError("geometry: failed")
    COMM.barrier()
    assert listing(base) == []


# -- names and units of what is written ------------------------------------------------------
def test_slugs_of_names_in_any_script_stay_distinct():
    """Experiment names become ASCII file-name prefixes: Latin ones as before, names in other
    scripts (or with accents) with a hash of the whole name, so two Chinese names do not
    collide (before: both "experiment"); long names are cut."""
    assert slug("cao 115") == "cao_115" and slug("a/b") == "a_b"
    a, b = slug("试验一"), slug("试验二")
    assert a != b and a.isascii() and b.isascii() and a.startswith("experiment_")
    assert slug("Probe Ä").startswith("Probe_A_") and slug("Probe Ä") != slug("Probe A")
    assert len(slug("x" * 300)) <= 70


def test_two_non_latin_names_accepted(tmp_path):
    """compare of two experiments named in Chinese: no longer refused as one prefix."""
    base = shared(tmp_path)
    if COMM.rank == 0:
        for d, n in (("a", "试验一"), ("b", "试验二")):
            exp = th.good_experiment()
            exp.name = n
            write_experiment(base / d, exp)
    COMM.barrier()
    args = cli.build_parser().parse_args(
        ["compare", str(base / "a"), str(base / "b"), "--terms", TERMS, "--out", str(base / "o")]
    )
    exps, _, _ = measure_cli.checked_setup(args)
    assert [e.name for e in exps] == ["试验一", "试验二"]


def test_per_point_in_mm_whatever_the_input_units(tmp_path):
    """Data in m and kN: per_point.csv holds mm (its columns say so), the same numbers as
    for the same data given in mm."""
    base = shared(tmp_path)
    if COMM.rank == 0:
        write_experiment(base / "mm", th.good_experiment())
        shutil.copytree(base / "mm", base / "m")
        toml = (base / "m" / "experiment.toml").read_text()
        toml = toml.replace('length = "mm"', 'length = "m"').replace('force = "N"', 'force = "kN"')
        toml = toml.replace("length = 40.0", "length = 0.04").replace(
            "width = 20.0", "width = 0.02"
        )
        (base / "m" / "experiment.toml").write_text(
            toml.replace("noise_std = 0.01", "noise_std = 1e-5")
        )
        for f in ("field.csv", "force.csv"):
            rows = (base / "m" / f).read_text().splitlines()
            scale = 1e-3  # mm -> m; N -> kN: the same factor
            body = [
                r.split(",")[:1] + [repr(float(v) * scale) for v in r.split(",")[1:]]
                for r in rows[1:]
                if r
            ]
            (base / "m" / f).write_text("\n".join([rows[0]] + [",".join(b) for b in body]))
    COMM.barrier()
    tables = []
    for d in ("mm", "m"):
        exp = load_experiment(base / d)

        class Pred:
            u = exp.u + 0.5

        path = base / f"{d}{COMM.rank}.csv"
        _per_point(path, exp, Pred, np.full(len(exp.X), 0.5 * np.sqrt(2)))
        tables.append(path.read_text().splitlines())
    assert tables[0][0] == "step,X_mm,Y_mm,ux_meas_mm,uy_meas_mm,ux_model_mm,uy_model_mm,error_mm"
    a, b = (np.array([[float(v) for v in r.split(",")] for r in t[1:]]) for t in tables)
    assert np.allclose(a, b, rtol=1e-12) and a[:, 1].max() == 38.0


def test_interrupt_during_publish_waits_for_it(tmp_path, monkeypatch):
    """SIGINT arriving between two renames of a publish is held until the publish is done:
    the handler (here one that records what OUT holds) sees every file and the record,
    never half of them (without the hold it runs right after the first rename)."""
    import signal

    import fabricsurf.cli.outdir as outdir

    base = shared(tmp_path)
    if COMM.rank == 0:
        (base / "D").mkdir()  # an existing OUT: its files are moved one by one
    COMM.barrier()
    seen, renames = [], []
    real_replace = os.replace

    def replace(src, dst):
        real_replace(src, dst)
        renames.append(dst)
        if len(renames) == 1:
            os.kill(os.getpid(), signal.SIGINT)

    previous = signal.signal(signal.SIGINT, lambda *a: seen.append(listing(base / "D")))
    try:
        with OutputDir(base / "D", COMM) as stage:
            for name in ("a.json", "b.json", "c.json"):
                write_json(COMM, stage / name, {})
            monkeypatch.setattr(outdir.os, "replace", replace)
    finally:
        signal.signal(signal.SIGINT, previous)
    if COMM.rank == 0:
        assert seen == [[MANIFEST, "a.json", "b.json", "c.json"]]
