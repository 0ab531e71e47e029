"""The Python API refuses what the command line refuses (issue 53, point 3): ``fit()`` and
``diagnose()`` called from Python check their inputs first
(:mod:`fabricsurf.inverse.fitting.preconditions`), before any forward solve, with the message
the command line gives, its options' names (``--terms a,b``, ``--params FILE``) replaced by the
arguments' (``terms [...]``, ``params``): (a) more moduli than data, (b) a zero starting
modulus, (c) a planar data set with an out-of-plane term."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from test_hardening import edits, good_experiment, replace, run_cli, shared_root, variant

import fabricsurf.inverse.diagnosis.diagnose as diagnose_mod
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.data import load_experiment
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.model.terms import make_term

COMM = MPI.COMM_WORLD
TERMS = "fibre_stretch,shear"


def zero_params(base: Path) -> None:
    (base / "zero.json").write_text(json.dumps({"shear": {"k_s": 0.0}}))


ONEPOINT = variant(
    "onepoint",
    edits(
        replace("experiment.toml", 'field = "field.csv"\n', ""),
        replace("experiment.toml", "\nnoise_std = 0.01\n", "\n"),
        replace("force.csv", "\n2,1.6,0.0", ""),
    ),
)
CASES = [  # id, DATA, --terms, --params, what the message says
    ("underdetermined", "onepoint", TERMS, None, r"fewer data than moduli"),
    ("zero-start", "good", TERMS, "zero.json", r"shear\.k_s = 0: fit and diagnose start"),
    (
        "planar-out-of-plane",
        "good",
        TERMS + ",twist",
        None,
        r"twist is an out-of-plane effect, and experiment 'synthetic'",
    ),
]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return shared_root(tmp_path_factory, "libchecks", [dict(make=ONEPOINT), dict(make=zero_params)])


def neutral(msg: str, terms: str, params: str | None) -> str:
    """The command line's message with the library's names for the inputs."""
    msg = msg.replace(f"--terms {terms}", f"terms {terms.split(',')}")
    msg = msg.replace("(fewer --terms, or --fixed)", "(fewer terms, or fixed)")
    msg = msg.replace("(fewer --terms)", "(fewer terms)").replace("from --terms", "from the terms")
    return msg.replace(f"--params {params}", "params") if params else msg


def model(terms: str, params: dict) -> list:
    return [make_term(n, **params.get(n, {})) for n in terms.split(",")]


class Recorder:
    """A forward model that tells its data and terms, and records every solve asked of it."""

    def __init__(self, exps, terms):
        self.experiments, self.model, self.comm, self.forward_runs = exps, terms, COMM, 0
        self.params = [(t, p) for t in terms for p in t.parameters()]
        self.names = [f"{t.name}.{p}" for t, p in self.params]
        self.solves = 0

    def values(self):
        return np.array([getattr(t, p) for t, p in self.params])

    def set_values(self, v):
        for (t, p), x in zip(self.params, v):
            setattr(t, p, float(x))

    def run(self, sens=False):
        self.solves += 1
        raise AssertionError("a forward solve before the checks")


def cli_message(command, root, data, terms, params, capsys, monkeypatch) -> str:
    monkeypatch.chdir(root)
    argv = [command, data, "--terms", terms, "--out", "out"] + (
        ["--params", params] if params else []
    )
    rc, msg = run_cli(argv, capsys)
    assert rc == 2, msg
    assert not (root / "out").exists()
    return msg.splitlines()[-1].split("error: ", 1)[1]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_fit_refuses_like_the_cli(case, root, capsys, monkeypatch):
    _, data, terms, pfile, pattern = case
    cli = cli_message("fit", root, data, terms, pfile, capsys, monkeypatch)
    params = json.loads((root / pfile).read_text()) if pfile else {}
    fm = Recorder([load_experiment(root / data)], model(terms, params))
    with pytest.raises(InputError) as err:
        fit(fm)
    assert fm.solves == 0
    assert re.search(pattern, str(err.value)), str(err.value)
    assert str(err.value) == neutral(cli, terms, pfile)


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_diagnose_refuses_like_the_cli(case, root, capsys, monkeypatch):
    _, data, terms, pfile, pattern = case
    built = []
    monkeypatch.setattr(diagnose_mod, "ForwardSet", lambda *a, **k: built.append(a))
    cli = cli_message("diagnose", root, data, terms, pfile, capsys, monkeypatch)
    params = json.loads((root / pfile).read_text()) if pfile else None
    with pytest.raises(InputError) as err:
        diagnose_mod.diagnose([load_experiment(root / data)], terms.split(","), params=params)
    assert not built
    assert re.search(pattern, str(err.value)), str(err.value)
    assert str(err.value) == neutral(cli, terms, pfile)


def test_in_memory_experiment_refused():
    """An experiment made in Python (no files): the same refusal, naming the terms."""
    fm = Recorder([good_experiment()], model(TERMS + ",normal_bending", {}))
    with pytest.raises(InputError, match=r"normal_bending is an out-of-plane effect"):
        fit(fm)
    assert fm.solves == 0
