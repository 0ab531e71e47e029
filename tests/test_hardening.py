"""Hardening of the command line: every bad input ends with one message naming the file, key or
option and exit status 2, on 1 rank and on 2 ranks alike (the status and the message are
compared across ranks); nothing given is silently ignored; --out is checked before any
computation and written atomically; a failure on rank 0 alone ends every rank (subprocess under
``mpirun -n 2``); the JIT compiler is quiet unless --verbose; --help shows defaults and units.

The table of rejected inputs in docs/input_errors.md is generated from the real messages of the
cases here and in tests/test_hardening_outputs.py: ``python
benchmarks/regenerate_input_errors.py`` rewrites it; a test there fails when it is stale.
"""

import csv
import importlib
import json
import logging
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from scipy import stats

import fabricsurf.cli as cli
import fabricsurf.cli.bias as bias_cli
from fabricsurf.cli import main
from fabricsurf.cli.options import check_bias_options
from fabricsurf.cli.outdir import OutputDir
from fabricsurf.discretise.output import StepLog, write_json
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.data import DataError, load_experiment, write_experiment
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import PROGRESS
from fabricsurf.model.terms import EFFECTS

COMM = MPI.COMM_WORLD
TERMS = "fibre_stretch,shear"  # forms compiled by the other CLI tests
DOC = Path(__file__).resolve().parents[1] / "docs" / "input_errors.md"


def good_experiment():
    """40 × 20 mm bias specimen, 4 × 2 DIC points, two steps (cheap: h = 10 mm default 2)."""
    exp = sy.template(40.0, 20.0, [0.8, 1.6], sy.grid_points(40.0, 20.0, 4, 2))
    exp.u = exp.u + 0.01
    exp.noise_std, exp.force_noise_std = 0.01, 0.01
    return exp


def shared_root(tmp_path_factory, name: str, cases: list[dict], good: bool = True) -> Path:
    """One directory shared by all ranks (rank 0's), holding ``good`` (unless not ``good``) and
    the inputs of ``cases``; the tests run with it as the working directory so messages hold
    relative names only. Every hardening module's ``root`` fixture is one of these."""
    base = Path(COMM.bcast(str(tmp_path_factory.mktemp(name)) if COMM.rank == 0 else None))
    if COMM.rank == 0:
        if good:
            write_experiment(base / "good", good_experiment())
        for c in cases:
            c["make"](base)
    COMM.barrier()
    return base


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return shared_root(tmp_path_factory, "hard", CASES)


def run_cli(argv, capsys) -> tuple[int, str]:
    """Exit status and rank 0's output; both must be the same on every rank."""
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    text = out.out + out.err
    if COMM.rank > 0:
        assert text == "", f"rank {COMM.rank} printed: {text}"
    text = COMM.bcast(text)
    assert COMM.allgather(rc) == [rc] * COMM.size
    return rc, text.strip()


# -- the cases: (id, input class, how to make it, command line, pattern of the message) -------
def variant(name: str, edit):
    """A copy of ``good`` called ``name`` changed by ``edit(directory)``."""

    def make(base: Path) -> None:
        shutil.copytree(base / "good", base / name)
        edit(base / name)

    return make


def replace(file: str, old, new):
    def edit(d: Path) -> None:
        data = (d / file).read_bytes()
        old_b, new_b = (x.encode() if isinstance(x, str) else x for x in (old, new))
        assert old_b in data, (old, file)
        (d / file).write_bytes(data.replace(old_b, new_b, 1))

    return edit


def params_file(name: str, content):
    def make(base: Path) -> None:
        (base / name).write_text(content if isinstance(content, str) else json.dumps(content))

    return make


def nothing(base: Path) -> None:
    return None


def field_in_metres(d: Path) -> None:
    rows = list(csv.reader((d / "field.csv").open()))
    body = [[r[0]] + [repr(float(v) / 1000) for v in r[1:]] for r in rows[1:]]
    (d / "field.csv").write_text("\n".join(",".join(r) for r in [rows[0], *body]) + "\n")


def edits(*fns):
    def edit(d: Path) -> None:
        for fn in fns:
            fn(d)

    return edit


def self_link(file: str):
    def edit(d: Path) -> None:
        (d / file).unlink()
        (d / file).symlink_to(file)

    return edit


def cantilever(path: str):
    """``good`` made a cantilever strip (field only, [loading] path ``path``; no uz)."""

    def edit(d: Path) -> None:
        toml = (d / "experiment.toml").read_text()
        for old, new in (
            ('test = "bias_extension"\nclamp = "gradient"', f'test = "cantilever"\npath = {path}'),
            ('force = "force.csv"\n', ""),
            ("force_noise_std = 0.01\n", ""),
        ):
            assert old in toml, old
            toml = toml.replace(old, new)
        (d / "experiment.toml").write_text(toml + "[material]\nareal_density_g_m2 = 200.0\n")
        (d / "force.csv").unlink()

    return edit


def make_file_out(base: Path) -> None:
    (base / "a_file").write_text("not a directory\n")


def cmp(data="good", *extra):
    return ["compare", data, "--terms", TERMS, "--out", "out", *extra]


def dgn(*extra):
    return ["diagnose", "good", "--terms", TERMS, "--out", "out", *extra]


CASES = [
    dict(
        id="params-typo",
        klass="`--params` naming a term that does not exist (typo)",
        make=params_file("typo.json", {"sheer": {"k_s": 0.8}}),
        argv=cmp("good", "--params", "typo.json"),
        pattern=r"typo.json: unknown term 'sheer'",
    ),
    dict(
        id="params-absent-term",
        klass="`--params` naming a term that is not in `--terms`",
        make=params_file("absent.json", {"geodesic_bending": {"A_g": 1.0}}),
        argv=cmp("good", "--params", "absent.json"),
        pattern=r"absent.json: term 'geodesic_bending' is not in the model",
    ),
    dict(
        id="params-unknown-modulus",
        klass="`--params` naming a modulus the term lacks",
        make=params_file("modulus.json", {"shear": {"k_l": 1.0}}),
        argv=cmp("good", "--params", "modulus.json"),
        pattern=r"modulus.json: term 'shear' has no parameter 'k_l'",
    ),
    dict(
        id="params-list",
        klass="`--params` that is not a JSON object (a list)",
        make=params_file("list.json", [0.8]),
        argv=cmp("good", "--params", "list.json"),
        pattern=r"list.json: expected \{\"term\": \{\"parameter\": value\}\}, got list",
    ),
    dict(
        id="params-flat",
        klass="`--params` with a number where a table of moduli belongs",
        make=params_file("flat.json", {"shear": 0.8}),
        argv=cmp("good", "--params", "flat.json"),
        pattern=r"flat.json: \"shear\" must map parameters to values",
    ),
    dict(
        id="params-negative",
        klass="`--params` with a negative or non-finite modulus",
        make=params_file("negative.json", {"shear": {"k_s": -1}}),
        argv=cmp("good", "--params", "negative.json"),
        pattern=r"negative.json: shear.k_s = -1 must be a finite number ≥ 0 \(N/mm\)",
    ),
    dict(
        id="params-not-json",
        klass="`--params` that is not valid JSON",
        make=params_file("broken.json", "{shear: 1"),
        argv=cmp("good", "--params", "broken.json"),
        pattern=r"broken.json: not valid JSON",
    ),
    dict(
        id="fit-zero-start",
        klass="`fit`/`diagnose` starting from a zero modulus",
        make=params_file("zero.json", {"shear": {"k_s": 0.0}}),
        argv=["fit", "good", "--terms", TERMS, "--params", "zero.json", "--out", "out"],
        pattern=r"zero.json: shear.k_s = 0: fit and diagnose start from these moduli",
    ),
    dict(
        id="terms-duplicate",
        klass="`--terms` naming a term twice",
        make=nothing,
        argv=["compare", "good", "--terms", "shear,shear", "--out", "out"],
        pattern=r"--terms: 'shear' is given twice",
    ),
    dict(
        id="terms-unknown",
        klass="`--terms` naming a term that does not exist",
        make=nothing,
        argv=["compare", "good", "--terms", "shear,sheer", "--out", "out"],
        pattern=r"--terms: unknown term 'sheer'; valid terms are: fibre_stretch",
    ),
    dict(
        id="toml-unknown-key",
        klass="unknown key in experiment.toml (`noise_sd`)",
        make=variant("noise_sd", replace("experiment.toml", "noise_std", "noise_sd")),
        argv=cmp("noise_sd"),
        pattern=r"experiment.toml: unknown key \[data\] noise_sd",
    ),
    dict(
        id="toml-unknown-table",
        klass="unknown table in experiment.toml",
        make=variant("table", replace("experiment.toml", "[units]", "[unit]")),
        argv=cmp("table"),
        pattern=r"experiment.toml: unknown key or table 'unit'",
    ),
    dict(
        id="field-1e300",
        klass="absurd displacement in field.csv (1e300)",
        make=variant("huge", replace("field.csv", ",0.01\r\n", ",1e300\r\n")),
        argv=cmp("huge"),
        pattern=r"field.csv line 2: displacement of 1e\+300 mm",
    ),
    dict(
        id="field-inf",
        klass="non-finite or empty cell in a CSV",
        make=variant("inf", replace("force.csv", "\n1,0.8,", "\n1,inf,")),
        argv=cmp("inf"),
        pattern=r"force.csv line 2: column displacement = 'inf' is not a "
        "finite number",
    ),
    dict(
        id="force-absurd",
        klass="absurd force in force.csv",
        make=variant("bigforce", replace("force.csv", "\n1,0.8,0.0", "\n1,0.8,1e12")),
        argv=cmp("bigforce"),
        pattern=r"force.csv line 2: force 1e\+12 N is not plausible",
    ),
    dict(
        id="units-m-numbers-mm",
        klass='`[units] length = "m"` with the sizes in mm',
        make=variant("metres", replace("experiment.toml", 'length = "mm"', 'length = "m"')),
        argv=cmp("metres"),
        pattern=r"experiment.toml: \[specimen\] 40000 x 20000 mm is not a "
        "plausible specimen",
    ),
    dict(
        id="field-in-m",
        klass="field.csv in m with the specimen in mm (points in a corner)",
        make=variant("fieldm", field_in_metres),
        argv=cmp("fieldm"),
        pattern=r"field.csv: all points lie in a 0.036 x 0.018 mm patch of the 40 x 20 mm "
        "specimen",
    ),
    dict(
        id="field-outside",
        klass="field point outside the specimen",
        make=variant("outside", replace("field.csv", "\n1,2.0,", "\n1,50.0,")),
        argv=cmp("outside"),
        pattern=r"field.csv line 2: point \(X, Y\) = \(50, 1\) mm is "
        "outside the specimen",
    ),
    dict(
        id="noise-absurd",
        klass="noise level larger than the specimen",
        make=variant("noise", replace("experiment.toml", "noise_std = 0.01", "noise_std = 1e3")),
        argv=cmp("noise"),
        pattern=r"\[data\] noise_std = 1e\+03 mm exceeds the specimen size",
    ),
    dict(
        id="latin1",
        klass="a CSV in Latin-1 (non-UTF-8 byte)",
        make=variant("latin1", replace("field.csv", "step,X", b"step\xe9,X")),
        argv=cmp("latin1"),
        pattern=r"field.csv line 1: byte 0xe9 is not UTF-8 \('é' in "
        "Windows-1252/Latin-1\\?\\)",
    ),
    dict(
        id="decimal-comma",
        klass="decimal comma in a comma-separated CSV",
        make=variant("deccomma", replace("force.csv", "\n1,0.8,", '\n1,"0,8",')),
        argv=cmp("deccomma"),
        pattern=r"force.csv line 2: column displacement = '0,8' is not a "
        "finite number \\(a decimal comma",
    ),
    dict(
        id="tab-separated",
        klass="tab-separated CSV",
        make=variant(
            "tabs",
            lambda d: (d / "force.csv").write_text(
                (d / "force.csv").read_text().replace(",", "\t")
            ),
        ),
        argv=cmp("tabs"),
        pattern=r"force.csv line 1: tab-separated header",
    ),
    dict(
        id="force-link-loop",
        klass="force.csv a symbolic link to itself",
        make=variant("forceloop", self_link("force.csv")),
        argv=cmp("forceloop"),
        pattern=r"force.csv: a symbolic link that loops \(force.csv -> force.csv\) in "
        "forceloop, not a file",
    ),
    dict(
        id="fibres-near-parallel",
        klass="fibre families less than 5° apart",
        make=variant("nearpar", replace("experiment.toml", "[45.0, -45.0]", "[45.0, 45.0001]")),
        argv=cmp("nearpar"),
        pattern=r"fibre_angles_deg = \[45.0, 45.0001\]: the two fibre "
        "families are 0.0001° apart, nearly parallel; they must cross at 5° or more",
    ),
    dict(
        id="bias-compression",
        klass="bias force curve with negative displacements",
        make=variant(
            "compress",
            edits(
                replace("force.csv", "\n1,0.8,0.0", "\n1,-0.8,-0.1"),
                replace("force.csv", "\n2,1.6,0.0", "\n2,-1.6,-0.2"),
            ),
        ),
        argv=cmp("compress"),
        pattern=r"force.csv: step 1: grip displacement \(mm\) -0.8 is "
        "negative; the 'bias_extension' test models extension",
    ),
    dict(
        id="cantilever-path",
        klass="cantilever load path outside (0, 1]",
        make=variant("cantpath", cantilever("[0.5, -1, 3, 1]")),
        argv=[
            "compare",
            "cantpath",
            "--terms",
            "fibre_stretch,shear,normal_bending",
            "--out",
            "out",
        ],
        pattern=r"experiment.toml: \[loading\] path: step 2: self-weight factor "
        r"-1 is outside \(0, 1\]",
    ),
    dict(
        id="cantilever-no-uz",
        klass="cantilever field without uz",
        make=variant("cantnouz", cantilever("[0.5, 1.0]")),
        argv=[
            "compare",
            "cantnouz",
            "--terms",
            "fibre_stretch,shear,normal_bending",
            "--out",
            "out",
        ],
        pattern=r"field.csv: no column uz; the 'cantilever' test is out of plane",
    ),
    dict(
        id="forces-all-zero",
        klass="forces all 0 without `force_noise_std`",
        make=variant("zeroforce", replace("experiment.toml", "force_noise_std = 0.01\n", "")),
        argv=cmp("zeroforce"),
        pattern=r"force.csv: every force is 0 and \[data\] "
        "force_noise_std is not given, so the misfit has no force scale",
    ),
    dict(
        id="names-collide",
        klass="experiment names equal as file names (`cao 115`, `cao_115`)",
        make=lambda base: [
            variant(n, replace("experiment.toml", '"synthetic"', f'"{v}"'))(base)
            for n, v in (("cao1", "cao 115"), ("cao2", "cao_115"))
        ],
        argv=["compare", "cao1", "cao2", "--terms", TERMS, "--out", "out"],
        pattern=r"experiments 'cao 115' and 'cao_115' \(experiment.toml: name\) give the same "
        "file name prefix 'cao_115_' in --out",
    ),
    dict(
        id="fit-underdetermined",
        klass="`fit` of more moduli than measured values",
        make=variant(
            "onepoint",
            edits(
                replace("experiment.toml", 'field = "field.csv"\n', ""),
                replace("experiment.toml", "\nnoise_std = 0.01\n", "\n"),
                replace("force.csv", "\n2,1.6,0.0", ""),
            ),
        ),
        argv=["fit", "onepoint", "--terms", TERMS, "--out", "out"],
        pattern=r"--terms fibre_stretch,shear: 3 moduli to fit \(fibre_stretch.k_l, "
        r"fibre_stretch.k_m, shear.k_s\) from 1 measured value \('synthetic': 1 force "
        r"value\): fewer data than moduli, the fit is under-determined",
    ),
    dict(
        id="diagnose-underdetermined",
        klass="`diagnose` of more free moduli than measured values",
        make=nothing,
        argv=["diagnose", "onepoint", "--terms", TERMS, "--out", "out"],
        pattern=r"3 moduli to fit .* from 1 measured value .*\(fewer --terms, or --fixed\)",
    ),
    dict(
        id="missing-data",
        klass="a DATA directory that does not exist",
        make=nothing,
        argv=cmp("nodata"),
        pattern=r"nodata: not a directory",
    ),
    dict(
        id="out-is-file",
        klass="`--out` is an existing file",
        make=make_file_out,
        argv=["compare", "good", "--terms", TERMS, "--out", "a_file"],
        pattern=r"--out a_file: exists and is not a directory",
    ),
    dict(
        id="out-under-file",
        klass="`--out` inside a file",
        make=nothing,
        argv=["compare", "good", "--terms", TERMS, "--out", "a_file/sub"],
        pattern=r"--out a_file/sub: a_file is a file, not a directory",
    ),
    dict(
        id="out-is-data",
        klass="`--out` is a DATA directory (its files would be overwritten)",
        make=nothing,
        argv=["compare", "good", "--terms", TERMS, "--out", "good"],
        pattern=r"--out good: it is the input DATA directory good; outputs must not overwrite",
    ),
    dict(
        id="out-inside-data",
        klass="`--out` inside a DATA directory",
        make=nothing,
        argv=["compare", "good", "--terms", TERMS, "--out", "good/results"],
        pattern=r"--out good/results: it lies inside the input DATA directory good",
    ),
    dict(
        id="out-contains-data",
        klass="`--out` containing a DATA directory",
        make=nothing,
        argv=["compare", "good", "--terms", TERMS, "--out", "."],
        pattern=r"--out \.: it contains the input DATA directory good",
    ),
    dict(
        id="out-is-params",
        klass="`--out` is the `--params` file",
        make=params_file("outp.json", {"shear": {"k_s": 0.8}}),
        argv=["bias", "--params", "outp.json", "--out", "outp.json"],
        pattern=r"--out outp.json: it is the input --params outp.json",
    ),
    dict(
        id="out-dangling-link",
        klass="`--out` a dangling symbolic link",
        make=lambda base: (base / "dangling").symlink_to("nowhere"),
        argv=["compare", "good", "--terms", TERMS, "--out", "dangling"],
        pattern=r"--out dangling: dangling is a symbolic link to nowhere, which does not exist",
    ),
    dict(
        id="out-link-loop",
        klass="`--out` under a symbolic link that loops",
        make=lambda base: (base / "loop").symlink_to("loop"),
        argv=["compare", "good", "--terms", TERMS, "--out", "loop/sub"],
        pattern=r"--out loop/sub: loop is a symbolic link that loops \(-> loop\)",
    ),
    dict(
        id="h-zero",
        klass="`--h 0` (or negative)",
        make=nothing,
        argv=cmp("good", "--h", "0"),
        pattern=r"--h 0: must be a positive element size in mm",
    ),
    dict(
        id="h-huge",
        klass="`--h` larger than half the specimen",
        make=nothing,
        argv=cmp("good", "--h", "1e5"),
        pattern=r"--h 100000: must be a positive element size in mm, at most 10",
    ),
    dict(
        id="steps-unknown",
        klass="`compare --steps` naming a step the data lack",
        make=nothing,
        argv=cmp("good", "--steps", "99"),
        pattern=r"--steps 99: step 99 is not a step of experiment 'synthetic' \(steps 1..2\)",
    ),
    dict(
        id="steps-garbage",
        klass="`compare --steps` that are not numbers",
        make=nothing,
        argv=cmp("good", "--steps", "last"),
        pattern=r"--steps last: expected comma-separated step numbers",
    ),
    dict(
        id="confirm-zero",
        klass="`diagnose --confirm 0`",
        make=nothing,
        argv=["diagnose", "good", "--terms", TERMS, "--confirm", "0", "--out", "out"],
        pattern=r"--confirm 0: must be at least 1",
    ),
    dict(
        id="max-effects-negative",
        klass="`diagnose --max-effects -1`",
        make=nothing,
        argv=["diagnose", "good", "--terms", TERMS, "--max-effects", "-1", "--out", "out"],
        pattern=r"--max-effects -1: must be at least 0",
    ),
    dict(
        id="fixed-no-params",
        klass="`diagnose --fixed` without the moduli of the fixed terms",
        make=params_file("nofixed.json", {"fibre_stretch": {"k_l": 2.0, "k_m": 2.0}}),
        argv=dgn("--fixed", "shear", "--params", "nofixed.json"),
        pattern=r"--fixed shear: a fixed term is held at its moduli from --params, and "
        r"shear.k_s is not given in --params nofixed.json",
    ),
    dict(
        id="fixed-all",
        klass="`diagnose --fixed` on every baseline term",
        make=nothing,
        argv=dgn("--fixed", "shear,fibre_stretch"),
        pattern=r"--fixed shear,fibre_stretch: every baseline term \(--terms "
        r"fibre_stretch,shear\) is fixed, so the baseline has no modulus to fit",
    ),
    dict(
        id="fixed-not-baseline",
        klass="`diagnose --fixed` naming a term not in `--terms`",
        make=nothing,
        argv=dgn("--fixed", "shear_locking"),
        pattern=r"--fixed shear_locking: 'shear_locking' is not a baseline term",
    ),
    dict(
        id="candidates-in-baseline",
        klass="`diagnose --candidates` only baseline terms",
        make=nothing,
        argv=dgn("--candidates", "shear"),
        pattern=r"--candidates shear: every candidate is already in the baseline \(--terms "
        r"fibre_stretch,shear\), so nothing would be tested",
    ),
    dict(
        id="candidates-unknown",
        klass="`diagnose --candidates` naming an unknown term",
        make=nothing,
        argv=dgn("--candidates", "sheer_locking"),
        pattern=r"--candidates sheer_locking: unknown term 'sheer_locking'; valid terms are",
    ),
    dict(
        id="candidates-hidden",
        klass="`diagnose --candidates` the data cannot see",
        make=nothing,
        argv=dgn("--candidates", "normal_bending"),
        pattern=r"--candidates normal_bending: these data cannot see normal_bending",
    ),
    dict(
        id="max-dofs-zero",
        klass="`diagnose --max-dofs 0` (the mesh selection's budget)",
        make=nothing,
        argv=dgn("--max-dofs", "0"),
        pattern=r"--max-dofs 0: must be at least 1 \(displacement unknowns of the finest mesh",
    ),
    dict(
        id="time-budget-negative",
        klass="`diagnose --time-budget -5`",
        make=nothing,
        argv=dgn("--time-budget", "-5"),
        pattern=r"--time-budget -5: must be a finite time in seconds > 0",
    ),
    dict(
        id="params-misfit",
        klass="`--params` given a misfit.json (not a moduli file)",
        make=params_file(
            "misfit.json",
            {
                "combined": 1.8,
                "chi2": 110.2,
                "n": 34,
                "experiments": [],
                "model": "fibre_stretch+shear",
                "provenance": {},
            },
        ),
        argv=cmp("good", "--params", "misfit.json"),
        pattern=r"--params misfit.json: this is a misfit report \(the misfit.json of compare, "
        r"fit or diagnose\), not a moduli file",
    ),
    dict(
        id="bias-h-zero",
        klass="`bias --h 0`",
        make=nothing,
        argv=["bias", "--h", "0", "--out", "out"],
        pattern=r"--h 0.0: must lie in \(0, 59.5\]",
    ),
    dict(
        id="bias-steps",
        klass="`bias --steps 0`",
        make=nothing,
        argv=["bias", "--steps", "0", "--out", "out"],
        pattern=r"--steps 0: must lie in \[1, "
        "1000\\]",
    ),
    dict(
        id="bias-out-clash",
        klass="`bias --out D` where D/bias_steps.csv is a directory",
        make=lambda base: (base / "clash" / "bias_steps.csv").mkdir(parents=True),
        argv=["bias", "--length", "40", "--width", "20", "--h", "10", "--out", "clash"],
        pattern=r"--out clash: clash/bias_steps.csv is a directory where a file of the same "
        "name is to be written",
    ),
    dict(
        id="bias-too-many-elements",
        klass="`bias --h` too fine for the memory (element count estimated before meshing)",
        make=nothing,
        argv=["bias", "--length", "230", "--width", "115", "--h", "0.05", "--out", "out"],
        pattern=r"--h 0.05: about 21,160,000 elements \(specimen 230 x 115 mm\), more than "
        r"--max-elements 400,000; they would take about 1,058 GB of memory",
    ),
    dict(
        id="compare-too-many-elements",
        klass="`--h` too fine for the memory",
        make=nothing,
        argv=cmp("good", "--h", "0.01"),
        pattern=r"--h 0.01: about 16,000,000 elements \('synthetic' 40 x 20 mm\), more than "
        r"--max-elements 400,000",
    ),
    dict(
        id="params-duplicate-key",
        klass="`--params` naming one modulus twice in a term",
        make=params_file("twice.json", '{"shear": {"k_s": 0.5, "k_s": 5.0}}'),
        argv=cmp("good", "--params", "twice.json"),
        pattern=r"--params twice.json: key 'k_s' is given twice in one object",
    ),
    dict(
        id="params-empty-term",
        klass="`--params` with a term that gives no modulus",
        make=params_file(
            "emptyterm.json", {"fibre_stretch": {"k_l": 2.0, "k_m": 2.0}, "shear": {}}
        ),
        argv=cmp("good", "--params", "emptyterm.json"),
        pattern=r"--params emptyterm.json: term 'shear' gives no parameter \(it has k_s\)",
    ),
    dict(
        id="shear-noise-90",
        klass="`[data] shear_noise_deg` of 90° or more",
        make=variant(
            "shearnoise",
            replace(
                "experiment.toml",
                "force_noise_std = 0.01",
                "force_noise_std = 0.01\nshear_noise_deg = 95",
            ),
        ),
        argv=cmp("shearnoise"),
        pattern=r"experiment.toml: \[data\] shear_noise_deg = 95 must be below 90",
    ),
    dict(
        id="bias-3d-term",
        klass="`bias --terms` with an out-of-plane effect",
        make=nothing,
        argv=["bias", "--terms", "fibre_stretch,shear,twist", "--out", "out"],
        pattern=r"--terms fibre_stretch,shear,twist: twist is an out-of-plane effect, and the "
        r"bias test is planar",
    ),
    dict(
        id="usage",
        klass="a missing argument (usage error)",
        make=nothing,
        argv=["fit", "good", "--out", "out"],
        pattern=r"the following arguments are required: --terms",
    ),
]


@pytest.fixture
def in_root(root, monkeypatch):
    monkeypatch.chdir(root)
    return root


def rejected_message(case: dict, root: Path, capsys, monkeypatch) -> str:
    """Run ``case["argv"]`` with the forward solvers replaced by recorders: exit 2, the
    message matching ``case["pattern"]``, nothing built and nothing written in ``root``."""
    import fabricsurf.inverse.forward.runs as forward

    # binds the real ForwardSet first
    importlib.import_module("fabricsurf.inverse.diagnosis.diagnose")
    built = []
    monkeypatch.setattr(forward, "ForwardSet", lambda *a, **k: built.append(a))
    monkeypatch.setattr(bias_cli, "BiasExtension", lambda *a, **k: built.append(a))
    before = sorted(p.name for p in root.iterdir())
    rc, msg = run_cli(case["argv"], capsys)
    assert rc == 2, msg
    assert re.search(case["pattern"], msg), (case["pattern"], msg)
    assert not built
    COMM.barrier()
    assert sorted(p.name for p in root.iterdir()) == before  # no output, no staging left
    return msg


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_rejected_before_any_solve(case, in_root, capsys, monkeypatch):
    """Each input class: exit 2 on every rank, one message, nothing computed or written."""
    msg = rejected_message(case, in_root, capsys, monkeypatch)
    assert [ln for ln in msg.splitlines() if "error:" in ln] == [msg.splitlines()[-1]], msg
    assert case["id"] == "usage" or len(msg.splitlines()) == 1, msg


# -- accepted variants: the same values as the plain file ----------------------------------------
def test_dialects_and_encodings_accepted(tmp_path):
    """Trailing blank line, BOM in the TOML, UTF-16 CSV, CRLF, semicolons with a decimal comma:
    exactly the values of the plain directory."""
    d0 = tmp_path / f"plain{COMM.rank}"
    write_experiment(d0, good_experiment())
    ref = load_experiment(d0)
    edits = {
        "blank": lambda d: (d / "field.csv").write_text((d / "field.csv").read_text() + "\n\n"),
        "bom": lambda d: (d / "experiment.toml").write_bytes(
            b"\xef\xbb\xbf" + (d / "experiment.toml").read_bytes()
        ),
        "utf16": lambda d: (d / "field.csv").write_bytes(
            (d / "field.csv").read_text().encode("utf-16")
        ),
        "crlf": lambda d: (d / "force.csv").write_bytes(
            (d / "force.csv").read_bytes().replace(b"\n", b"\r\n")
        ),
        "semicolon": lambda d: [
            (d / f).write_text((d / f).read_text().replace(",", ";").replace(".", ","))
            for f in ("field.csv", "force.csv")
        ],
    }
    for name, edit in edits.items():
        d = tmp_path / f"{name}{COMM.rank}"
        shutil.copytree(d0, d)
        edit(d)
        exp = load_experiment(d)
        for a, b in ((exp.X, ref.X), (exp.u, ref.u), (exp.force, ref.force), (exp.path, ref.path)):
            assert np.array_equal(a, b), name


def test_noise_level_without_its_data_is_said(tmp_path, caplog):
    """A [data] noise key whose data file is absent scales nothing: rank 0 warns (once)."""
    d = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None)) / "forceonly"
    if COMM.rank == 0:
        exp = good_experiment()
        exp.field_step, exp.X, exp.u = np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2))
        write_experiment(d, exp)
        toml = d / "experiment.toml"
        toml.write_text(toml.read_text() + "noise_std = 0.01\n")
    COMM.barrier()
    load_experiment(d)
    load_experiment(d)
    said = "[data] noise_std is given but [data] field is not: the noise level is not used"
    warned = [r for r in caplog.records if said in r.getMessage()]
    assert len(warned) == (COMM.rank == 0) and all(r.levelno == logging.WARNING for r in warned)


def test_loader_messages_name_file_and_line(tmp_path):
    """The loader's own errors are DataError (an InputError) naming the file and line."""
    d = tmp_path / f"l{COMM.rank}"
    write_experiment(d, good_experiment())
    (d / "experiment.toml").write_bytes((d / "experiment.toml").read_bytes() + b"# caf\xe9\n")
    with pytest.raises(DataError, match=r"experiment.toml line \d+: byte 0xe9") as e:
        load_experiment(d)
    assert isinstance(e.value, InputError)


# -- what is used is recorded; outputs are published whole ---------------------------------------
def test_misfit_records_what_was_used(in_root, capsys):
    """A compare run records terms, the exact moduli of --params, mesh size, inputs and
    versions; OUT gets the user's umask, not 0700."""
    if COMM.rank == 0:
        (in_root / "used.json").write_text(
            json.dumps({"fibre_stretch": {"k_l": 1.0, "k_m": 1.0}, "shear": {"k_s": 0.8}})
        )
    COMM.barrier()
    rc, msg = run_cli(
        [
            "compare",
            "good",
            "--terms",
            TERMS,
            "--params",
            "used.json",
            "--h",
            "10",
            "--out",
            "used",
        ],
        capsys,
    )
    assert rc == 0, msg
    m = json.loads((in_root / "used" / "misfit.json").read_text())
    prov = m["provenance"]
    assert prov["terms"] == ["fibre_stretch", "shear"] and prov["h_mm"] == [10.0]
    assert prov["params"] == {"fibre_stretch": {"k_l": 1.0, "k_m": 1.0}, "shear": {"k_s": 0.8}}
    assert prov["inputs"] == ["good"] and prov["ranks"] == COMM.size
    assert set(prov["versions"]) >= {"fabricsurf", "dolfinx", "petsc4py", "python"}
    umask = os.umask(0)
    os.umask(umask)
    assert (in_root / "used").stat().st_mode & 0o777 == 0o777 & ~umask
    assert not list(in_root.glob(".used.partial-*"))


def test_solver_failure_reports_step_from_1(in_root, capsys):
    """All moduli 0: the first load step cannot converge. The message counts from 1 (as the
    files do), gives the SNES reason in words, and failure.json is published with what was
    used; no misfit.json."""
    if COMM.rank == 0:
        (in_root / "soft.json").write_text(
            json.dumps({"fibre_stretch": {"k_l": 0.0, "k_m": 0.0}, "shear": {"k_s": 0.0}})
        )
    COMM.barrier()
    rc, msg = run_cli(
        [
            "compare",
            "good",
            "--terms",
            TERMS,
            "--params",
            "soft.json",
            "--h",
            "10",
            "--out",
            "failed",
        ],
        capsys,
    )
    assert rc == 2
    assert re.search(
        r"failed: load step 1 \(target 0.8\) failed: .*DIVERGED_[A-Z_]+ \(-\d+\)", msg
    ), msg
    assert msg.endswith("the failure report is in failed/failure.json")
    report = json.loads((in_root / "failed" / "failure.json").read_text())
    assert report["error"] in msg and report["provenance"]["params"]["shear"] == {"k_s": 0.0}
    assert report["converged_steps"] == [] and report["experiment"]
    assert sorted(p.name for p in (in_root / "failed").iterdir()) == [
        ".fabricsurf-run.json",
        "failure.json",
    ]


def test_start_failure_names_experiment_step_and_load():
    """A fit whose starting model cannot follow the load path says with which moduli, in which
    experiment, at which step and load (and keeps what had converged for failure.json)."""
    from fabricsurf.discretise.stepping import LoadStepError
    from fabricsurf.inverse.fitting.fit import fit

    class Diverging:  # a forward model whose start fails at step 3 of experiment 'strip45'
        names, comm, forward_runs = ["normal_bending.k_b"], COMM, 0

        def __init__(self):
            self.params, self.v = [(EFFECTS["normal_bending"](), "k_b")], np.array([1e-4])

        def values(self):
            return self.v.copy()

        def set_values(self, v):
            self.v = np.array(v, float)

        def run(self, sens=False):
            raise LoadStepError(
                "load step 3 (target 0.75) failed: DIVERGED_LINE_SEARCH (-6)",
                step=3,
                target=0.75,
                last_load=0.5,
                reason=-6,
                partial="converged",
                experiment="strip45",
            )

    with pytest.raises(LoadStepError) as err:
        fit(Diverging(), scale_start=False)
    assert str(err.value) == (
        "fit: the initial model (normal_bending.k_b = 0.0001) does not "
        "follow the load path of experiment 'strip45': load step 3 "
        "(target 0.75) failed: DIVERGED_LINE_SEARCH (-6)"
    )
    e = err.value
    assert (e.experiment, e.step, e.target, e.partial) == ("strip45", 3, 0.75, "converged")


def test_scanned_start_that_breaks_the_model_falls_back(caplog):
    """The decade scan ranks starts on the scout mesh; when the scanned start
    does not follow the load path on the fit's mesh (a modulus the data hardly see, scanned
    down to where the model breaks), the fit says so and starts from the given moduli."""
    from toy_forward import ToyForward

    from fabricsurf.discretise.stepping import LoadStepError
    from fabricsurf.inverse.fitting.fit import fit

    class Membrane(ToyForward):  # chi2 = (log k - log best)^2; the fine model fails below k = 0.01
        def __init__(self, best, floor):
            super().__init__(["a.k"], [1.0], COMM)
            self.best, self.floor = best, floor

        def run(self, sens=False):
            if self.v[0] < self.floor:
                raise LoadStepError(
                    f"load step 2 (target 0.5) failed at k = {self.v[0]:g}",
                    step=2,
                    target=0.5,
                    experiment="strip45",
                )
            return super().run(sens)

        def residuals(self, pred):
            return np.log(pred / self.best), np.array([[1.0 / pred[0]]])

    fm = Membrane(best=0.05, floor=0.01)
    fm.scout = Membrane(best=1e-4, floor=0.0)  # the scout mesh carries (and prefers) 1e-4
    caplog.set_level(PROGRESS, logger="fabricsurf")
    res = fit(fm)
    out = caplog.text
    assert np.isclose(res.values[0], 0.05, rtol=1e-4)
    if COMM.rank == 0:
        assert "start after the scale scan: a.k = 0.0001" in out
        assert (
            "the scanned start fails (fit: the initial model (a.k = 0.0001) does not "
            "follow the load path of experiment 'strip45': load step 2 (target 0.5) "
            "failed at k = 0.0001); starting from the given moduli instead"
        ) in out


def test_undetermined_moduli_named_not_given_a_plus_minus():
    """Data that see only the product k_l·k_m (a rank-1 Fisher matrix for two moduli) give no ±
    of 1e-13: the fit names the undetermined combination, reports the product's geometric mean
    (the combination that is determined) with its interval, and the printed result gives
    neither modulus a ±; a modulus whose interval would span zero is not identifiable."""
    from fabricsurf.inverse.diagnosis.result_text import result_lines
    from fabricsurf.inverse.fitting.fit import fit

    noise = np.array([0.1, -0.1, 0.05, -0.05, 0.2, -0.2, 0.0, 0.0])

    class Product:  # r = log k_l + log k_m - log 6 + noise, measured 8 times (noise 1)
        names, comm, forward_runs, noise_known = ["a.k_l", "a.k_m"], COMM, 0, True

        def __init__(self):
            self.params, self.v = [(None, "k_l"), (None, "k_m")], np.array([1.0, 1.0])

        def values(self):
            return self.v.copy()

        def set_values(self, v):
            self.v = np.array(v, float)

        def run(self, sens=False):
            return self.v.copy()

        def residuals(self, pred):
            r = np.log(pred[0]) + np.log(pred[1]) - np.log(6.0) + noise
            return r, np.tile(1.0 / pred, (8, 1))

        def misfit(self, pred):
            return {}

    res = fit(Product(), scale_start=False)
    assert np.isclose(res.values.prod(), 6.0)
    assert res.undetermined == ["0.71 log a.k_l - 0.71 log a.k_m"]
    u = res.as_dict()
    assert u["undetermined"] == res.undetermined
    assert not u["moduli"]["a.k_l"]["identifiable"] and not u["moduli"]["a.k_m"]["identifiable"]
    assert u["std"] == {"a.k_l": None, "a.k_m": None}  # not a std of 0 (issue 41)
    assert u["moduli"]["a.k_l"]["std_statistical"] is None
    (comb,) = u["identifiable_combinations"]
    # σ of log(k_l k_m)/2 is (1/2)/√8 (8 unit-noise data), Student's t with 8 - 2 dof
    half = stats.t.ppf(0.975, 6) * 0.5 / np.sqrt(8.0)
    assert np.isclose(comb["value"], np.sqrt(6.0))
    assert np.allclose(comb["ci95"], np.sqrt(6.0) * np.exp([-half, half]))
    assert np.allclose([comb["weights"]["a.k_l"], comb["weights"]["a.k_m"]], 0.5)
    lines = result_lines(u)
    assert lines[:2] == [
        f"  a.k_l = {res.values[0]:.5g} (not determined by the data on its own)",
        f"  a.k_m = {res.values[1]:.5g} (not determined by the data on its own)",
    ]
    assert lines[2].startswith("  determined combination: a.k_l^0.5 · a.k_m^0.5 = 2.4495")
    assert lines[3] == (
        "  not determined by the data (rank-deficient Fisher matrix): 0.71 log "
        "a.k_l - 0.71 log a.k_m"
    )
    assert not any("±" in ln for ln in lines)


def test_publish_all_or_nothing_and_collective(tmp_path):
    """A publish that would replace a directory by a file moves nothing, keeps the staging
    directory and raises the same InputError on every rank (it runs on rank 0 only)."""
    base = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))
    out = base / "out"
    if COMM.rank == 0:
        (out / "b.csv").mkdir(parents=True)
    COMM.barrier()
    with pytest.raises(InputError, match=r"b\.csv is a directory where a file") as e:
        with OutputDir(out, COMM) as stage:
            write_json(COMM, stage / "a.json", {"x": 1})
            write_json(COMM, stage / "b.csv", {"x": 2})
    kept = stage.with_name(stage.name.replace(".partial-", ".unpublished-"))
    assert str(kept) in str(e.value)
    assert sorted(p.name for p in out.iterdir()) == ["b.csv"]
    assert sorted(p.name for p in kept.iterdir()) == ["a.json", "b.csv"]


def test_max_elements_overrides_the_size_guard():
    """--max-elements raises the limit (the estimate is 2 per h × h square);
    a limit below 1 is refused naming the option."""
    args = cli.build_parser().parse_args(
        ["bias", "--length", "230", "--width", "115", "--h", "0.05", "--max-elements", "30000000"]
    )
    assert check_bias_options(args) == 0.25 * 230
    args.max_elements = 0
    with pytest.raises(InputError, match=r"--max-elements 0: must be at least 1"):
        check_bias_options(args)


def test_out_symlink_resolved(tmp_path):
    """--out a symbolic link to a directory elsewhere (or not yet made): the
    link is resolved first, the staging directory is made beside the target (a rename cannot
    cross file systems) and the results land in the target; no staging directory is left."""
    base = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))
    if COMM.rank == 0:
        (base / "elsewhere" / "target").mkdir(parents=True)
        (base / "links").mkdir()
        (base / "links" / "out").symlink_to(base / "elsewhere" / "target")
    COMM.barrier()
    with OutputDir(base / "links" / "out", COMM) as stage:
        assert stage.parent == base / "elsewhere"
        write_json(COMM, stage / "a.json", {"x": 1})
    COMM.barrier()
    assert (base / "elsewhere" / "target" / "a.json").is_file()
    assert (base / "links" / "out").is_symlink()
    assert sorted(p.name for p in (base / "elsewhere").iterdir()) == ["target"]
    assert sorted(p.name for p in (base / "links").iterdir()) == ["out"]


def test_failure_on_one_rank_raised_on_all(tmp_path):
    """An exception on the last rank only, inside the output context, is raised on every rank
    with the same message, and nothing is published."""
    base = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))
    with pytest.raises(InputError, match="only the last rank"):
        with OutputDir(base / "o", COMM) as stage:
            write_json(COMM, stage / "a.json", {})
            if COMM.rank == COMM.size - 1:
                raise InputError("only the last rank")
    COMM.barrier()
    assert not (base / "o").exists() and not list(base.glob(".o.partial-*"))


def test_rank0_write_failure_raised_on_all(tmp_path):
    """StepLog writes on rank 0; a failure there (its directory is a file) is an OSError on
    every rank, not a hang in the next collective call."""
    base = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))
    if COMM.rank == 0:
        (base / "log").write_text("a file, not a directory")
    COMM.barrier()
    log = StepLog(COMM, base / "log")
    with pytest.raises(OSError, match="log"):
        log.add(step=1, force=1.0)
    assert COMM.allreduce(1) == COMM.size


# -- a rank-0-only failure under mpirun ends every rank -------------------------------------------
@pytest.mark.skipif(COMM.size > 1, reason="starts mpirun -n 2 itself (serial session only)")
@pytest.mark.parametrize("command", ["bias", "compare"])
def test_rank0_only_failure_under_mpirun(command, tmp_path):
    """``mpirun -n 2 fabricsurf …`` where only rank 0 fails: bias checks --out on rank 0 (before
    computing); compare fails in the publish, after the solve. Both end within seconds on both
    ranks with status 2 and one message; nothing is published."""
    write_experiment(tmp_path / "good", good_experiment())
    clash = {"bias": "bias_steps.csv", "compare": "error_map.png"}[command]
    (tmp_path / "D" / clash).mkdir(parents=True)
    args = {
        "bias": [
            "bias",
            "--length",
            "40",
            "--width",
            "20",
            "--h",
            "10",
            "--steps",
            "1",
            "--terms",
            TERMS,
        ],
        "compare": ["compare", "good", "--terms", TERMS, "--h", "10"],
    }[command]
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    t0 = time.perf_counter()
    p = subprocess.run(
        ["mpirun", "-n", "2", sys.executable, "-m", "fabricsurf", *args, "--out", "D"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=240,
    )
    seconds = time.perf_counter() - t0
    lines = [ln for ln in (p.stdout + p.stderr).splitlines() if "error:" in ln]
    assert p.returncode == 2, p.stdout + p.stderr
    expected = (
        f"fabricsurf {command}: error: --out D: D/{clash} is a directory where a file "
        "of the same name is to be written"
    )
    assert len(lines) == 1 and lines[0].startswith(expected), lines
    if command == "compare":  # after the solve: the results are kept and named
        assert re.search(r"nothing was published, the results are in \.D\.unpublished-", lines[0])
    assert sorted(q.name for q in (tmp_path / "D").iterdir()) == [clash]
    print(f"mpirun -n 2 {command}: exit {p.returncode} after {seconds:.1f} s")
    assert seconds < 120


def test_interrupt_cleanup_by_one_rank_without_mpi(tmp_path):
    """The clean-up the signal handler runs (every rank calls it, no MPI
    call): exactly one rank removes the staging directory (or publishes it with its report)
    and gets the message; nothing else is left."""
    import fabricsurf.cli.outdir as outdir
    from fabricsurf.cli.interrupts import interrupted

    base = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))
    msgs = {}
    for name, keep in (("a", False), ("b", True)):
        od = OutputDir(base / name, COMM, keep_on_error=keep)
        stage = od.__enter__()
        write_json(COMM, stage / "x.json", {})
        od.on_interrupt = lambda st: (st / "failure.json").write_text("{}") and "; see failure.json"
        msgs[name] = COMM.allgather(interrupted("SIGTERM"))
        outdir.OPEN_DIRS.remove(od)
        COMM.barrier()
    assert [m for m in msgs["a"] if m] == [
        f"interrupted by SIGTERM; nothing was published to {base / 'a'}"
    ]
    assert [m for m in msgs["b"] if m] == ["interrupted by SIGTERM; see failure.json"]
    assert sorted(p.name for p in base.iterdir()) == ["b"]
    assert sorted(p.name for p in (base / "b").iterdir()) == [
        ".fabricsurf-run.json",
        "failure.json",
        "x.json",
    ]


def _interrupt(args: list[str], ranks: int, cwd: Path, after: str) -> tuple[int, str]:
    """Start ``fabricsurf ARGS`` (under ``mpirun -n ranks`` when ranks > 1), send SIGINT once
    its standard output shows ``after``; the exit status and the output, standard error first.
    The two streams go to separate files: mpirun forwards each in its own chunks, so one
    shared file can hold a progress line cut in two by an error message."""
    import signal

    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [sys.executable, "-m", "fabricsurf", *args]
    out, err = cwd / "out.txt", cwd / "err.txt"
    with open(out, "w") as fo, open(err, "w") as fe:
        p = subprocess.Popen(
            ["mpirun", "-n", str(ranks), *cmd] if ranks > 1 else cmd,
            cwd=cwd,
            env=env,
            stdout=fo,
            stderr=fe,
        )
        t0 = time.perf_counter()
        while after not in out.read_text() and p.poll() is None:
            assert time.perf_counter() - t0 < 180, out.read_text() + err.read_text()
            time.sleep(0.1)
        assert p.poll() is None, "ended before the interrupt: " + out.read_text() + err.read_text()
        p.send_signal(signal.SIGINT)
        p.wait(timeout=120)
    text = err.read_text() + "\n" + out.read_text()
    out.unlink()
    err.unlink()
    return p.returncode, text


@pytest.mark.skipif(COMM.size > 1, reason="starts mpirun -n 2 itself (serial session only)")
@pytest.mark.parametrize("ranks", [1, 2])
def test_interrupted_bias_publishes_converged_steps(ranks, tmp_path):
    """SIGINT during ``bias`` (mpirun turns it into SIGTERM on every rank):
    one message "interrupted … at step k", the converged steps' log and a failure.json that
    says "interrupted at step k" are published, the fields (an HDF5 file cut open, which h5py
    could not read) are not, and no staging directory or lock is left. Exit status 130
    serially; under mpirun, mpirun's own (Open MPI 4.1 returns 1 when it is interrupted)."""
    rc, out = _interrupt(
        [
            "bias",
            "--length",
            "40",
            "--width",
            "20",
            "--h",
            "2",
            "--steps",
            "400",
            "--ubar",
            "20",
            "--terms",
            TERMS,
            "--out",
            "D",
        ],
        ranks,
        tmp_path,
        "step 3/400",
    )
    lines = [ln for ln in out.splitlines() if "interrupted" in ln]
    assert (rc == 130 if ranks == 1 else rc != 0) and len(lines) == 1, (rc, out)
    m = re.fullmatch(
        r"fabricsurf bias: interrupted by SIG(INT|TERM) at step (\d+) of 400; the "
        r"step log of the (\d+) converged steps \(bias_steps.csv, .json\) and "
        r"failure.json are in D; the fields \(bias.xdmf, bias.h5\) are not kept: "
        r"an interrupted HDF5 file cannot be read back",
        lines[0],
    )
    assert sorted(p.name for p in (tmp_path / "D").iterdir()) == [
        ".fabricsurf-run.json",
        "bias_steps.csv",
        "bias_steps.json",
        "failure.json",
    ]
    assert m and int(m[2]) == int(m[3]) + 1 and int(m[3]) >= 3, lines
    report = json.loads((tmp_path / "D" / "failure.json").read_text())
    assert report["error"] == f"interrupted at step {m[2]}"
    assert report["converged_steps"] == int(m[3]) and report["provenance"]["ranks"] == ranks
    rows = list(csv.DictReader((tmp_path / "D" / "bias_steps.csv").open()))
    assert len(rows) >= int(m[3])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["D"]


@pytest.mark.skipif(COMM.size > 1, reason="starts mpirun -n 2 itself (serial session only)")
def test_interrupted_fit_under_mpirun_leaves_nothing(tmp_path):
    """SIGINT to ``mpirun -n 2 … fit``: one message on every way out, no
    output and no staging directory."""
    write_experiment(tmp_path / "good", good_experiment())
    rc, out = _interrupt(
        ["fit", "good", "--terms", TERMS, "--h", "0.5", "--out", "D"],
        2,
        tmp_path,
        "fit iteration 1",
    )
    lines = [ln for ln in out.splitlines() if "interrupted" in ln]
    assert rc != 0 and lines == [
        "fabricsurf fit: interrupted by SIGTERM; nothing was published to D"
    ], out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good"]


# -- quiet compiler, help, vocabulary ----------------------------------------------------------
def _compile_new_form(args) -> int:
    """A form no cache holds (a value drawn on rank 0): the JIT compiles it."""
    import ufl
    from dolfinx import fem, mesh

    k = COMM.bcast(int(time.time_ns() % 10**9) if COMM.rank == 0 else None)
    m = mesh.create_unit_square(COMM, 1, 1)
    x = ufl.SpatialCoordinate(m)
    fem.form(x[0] * (1 + x[1] / (k + 7)) * ufl.dx)
    return 0


def test_compiler_quiet_unless_verbose(capfd, caplog, monkeypatch):
    """The C compiler lines that cffi logs through the root logger (INFO, "running build_ext",
    the gcc command lines) are not even emitted by default; --verbose lets them through.
    (Compiles two tiny forms.)"""
    monkeypatch.setattr(cli, "cmd_terms", _compile_new_form)
    assert main(["terms"]) == 0
    quiet = capfd.readouterr()
    assert "INFO" not in quiet.out + quiet.err and "gcc" not in quiet.out + quiet.err
    assert not [r for r in caplog.records if r.levelno < logging.WARNING]
    assert main(["terms", "--verbose"]) == 0
    if COMM.rank == 0:  # rank 0 compiles, the others load the result
        assert any("build_ext" in r.getMessage() for r in caplog.records), caplog.records
    assert logging.root.manager.disable == logging.NOTSET  # main leaves logging as it was


def test_help_shows_defaults_and_units(capsys):
    """Every option with a default shows it (or its help describes it); --params and --h say
    their units; the exit status of --help is 0, of a usage error 2, on every rank."""
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.choices and "bias" in a.choices).choices
    for name, p in sub.items():
        for a in p._actions:
            if a.dest in ("help", "verbose", "quiet") or a.required or a.option_strings == []:
                continue
            text = p.formatter_class("x")._get_help_string(a)
            assert "default" in text or a.default is False, (name, a.dest, text)
            if a.dest in ("h", "length", "width", "ubar"):
                assert "mm" in text, (name, a.dest)
            if a.dest == "params":
                assert "N/mm" in text and "N·mm" in text, (name, text)
            if a.dest == "terms":
                assert all(e in text for e in EFFECTS), (name, text)
    for name in sub:
        rc, out = run_cli([name, "--help"], capsys)
        assert rc == 0 and out.startswith(f"usage: fabricsurf {name}")
    assert run_cli(["nonsense"], capsys)[0] == 2


def test_terms_lists_vocabulary(capsys):
    """`fabricsurf terms`: every name, each modulus with its unit, and its formula."""
    rc, out = run_cli(["terms"], capsys)
    assert rc == 0
    for name, cls in EFFECTS.items():
        line = next(ln for ln in out.splitlines() if ln.startswith(name + " "))
        for p in cls.parameters():
            assert f"{p} ({cls.units[p]})" in line, (name, p)
        assert cls.__doc__.strip().splitlines()[0] in out
