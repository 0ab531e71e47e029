"""Every demo runs in its quick mode as a user runs it, under ``mpirun -n 2`` in a process of
its own, and passes its own checks; then its summary.json meets the checks the demo declares
(its module-level ``CHECKS``, read from the source: fabricsurf.cli.demo) and its output holds
no compiler message.

As a user runs it: a copy of the demo outside the repository, run by the python of a fresh
virtual environment (on the system's FEniCSx) that holds a wheel of the package, so a demo that
needs anything not installed fails. The
source of every demo is also scanned: it imports no research code and does not touch
``sys.path``.

A process of its own: the demos do not share the PETSc options database, the JIT state or the
memory of the pytest session. These tests start their own ranks, so they run in the serial
session only and skip in the 2-rank one. dolfinx runs its demos on 1 rank as well; here the
1-rank physics of each demo is the library's, asserted by its own tests (test_bias_extension,
test_diagnose*, test_dispersion, test_hypar, test_hemisphere), and 1 = 2 ranks by
test_parallel and test_hemisphere, so a serial demo run would repeat them at minutes of cost.

Every demo runs here, none skipped: each quick mode takes about a minute at most on 2 ranks
with the forms compiled. The three heaviest say in their source how: the woven-fabric demo fits
every other point of its force curve, the bending demo starts its joint fit where its fits of
each strip ended, and the DIC demo is quick as it is (about 20 s; its import is also
tests/test_dic.py's)."""

import ast
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from mpi4py import MPI

from fabricsurf.cli.demo import declared, failures

ROOT = Path(__file__).resolve().parents[1]
DEMOS = ROOT / "demos"
QUICK = {
    "demo_hypar.py": ["--quick"],
    "demo_dispersion.py": ["--quick"],
    "demo_hidden_effect.py": ["--quick"],
    "demo_bias_extension.py": ["--quick"],
    "demo_bending.py": ["--quick"],
    "demo_woven_fabric.py": ["--quick"],
    "demo_forming.py": ["--quick"],
    "demo_double_dome.py": ["--quick"],
    "demo_dic.py": ["--quick"],
    "demo_new_effect.py": ["--quick"],
}
RANKS = 2
# what FFCx, UFL and cffi/distutils print while compiling a form
COMPILER = re.compile(
    r"^(INFO:|DEBUG:|.*\bgcc\b|.*\bcc1\b|running build_ext|building '|"
    r"Compiling form|Compiler stage)",
    re.M,
)
ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_rmaps_base_oversubscribe": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MPLBACKEND": "Agg",
}


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> str:
    """The python of a fresh virtual environment holding a wheel of the package (built from a
    copy of the sources, so nothing is written into the checkout) over the system packages."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    for pkg in ("fabricsurf", "geometry"):
        shutil.copytree(ROOT / pkg, src / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    pip = ["-m", "pip", "-q", "--disable-pip-version-check"]
    subprocess.run(
        [
            sys.executable,
            *pip,
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(tmp / "dist"),
            str(src),
        ],
        check=True,
        capture_output=True,
    )
    base = getattr(sys, "_base_executable", sys.executable)
    subprocess.run(
        [base, "-m", "venv", "--system-site-packages", str(tmp / "venv")],
        check=True,
        capture_output=True,
    )
    python = str(tmp / "venv" / "bin" / "python")
    wheel = next((tmp / "dist").glob("fabricsurf-*.whl"))
    subprocess.run(
        [python, *pip, "install", "--no-deps", "--no-index", str(wheel)],
        check=True,
        capture_output=True,
    )
    return python


def run_demo(script: Path, out: Path, python: str) -> str:
    """Run the demo ``script`` in quick mode on RANKS ranks with ``python``, from the directory
    above ``out``; its output (stdout and stderr)."""
    cmd = ["mpirun", "-n", str(RANKS), python, str(script), "--out", str(out), *QUICK[script.name]]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    p = subprocess.run(
        cmd, env=dict(env, **ENV), capture_output=True, text=True, timeout=1800, cwd=out.parent
    )
    text = p.stdout + p.stderr
    assert p.returncode == 0, f"{' '.join(cmd)} exited {p.returncode}:\n{text[-4000:]}"
    return text


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="starts its own ranks from the serial session")
@pytest.mark.parametrize("name", [n for n in sorted(QUICK) if (DEMOS / n).is_file()])
def test_demo_runs_and_meets_its_checks(name, tmp_path, request):
    checks = declared(DEMOS / name)
    assert checks, f"{name} declares no checks"
    script, python = tmp_path / name, request.getfixturevalue("installed")
    shutil.copy(DEMOS / name, script)
    text = run_demo(script, tmp_path / "out", python)
    assert not COMPILER.search(text), f"compiler output reached the user:\n{text[-4000:]}"
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert failures(summary, checks) == []


def test_checks_are_read_and_applied(tmp_path):
    """The checks machinery itself: ranges, presence, equality and ``*`` over a list; a
    missing entry and a value out of range are failures, not passes."""
    script = tmp_path / "demo_x.py"
    script.write_text("import numpy\nCHECKS = {'a/*': (0, 1), 'b': ..., 'c': 'x'}\n")
    checks = declared(script)
    assert failures({"a": [0, 0.5, 1], "b": None, "c": "x"}, checks) == []
    bad = failures({"a": [0.5, 2], "c": "y"}, checks)
    assert len(bad) == 3 and "a/1 = 2" in bad[0] and "no /b" in bad[1], bad


def outside_the_package(script: Path) -> list[str]:
    """What in a demo's source reaches beyond the installed packages: imports of the research
    code (benchmarks/) and any use of ``sys.path``."""
    bad = []
    for node in ast.walk(ast.parse(script.read_text(), str(script))):
        if isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            mods = [node.module or ""]
        elif (
            isinstance(node, ast.Attribute)
            and node.attr == "path"
            and isinstance(node.value, ast.Name)
            and node.value.id == "sys"
        ):
            bad.append((node.lineno, "sys.path"))
            continue
        else:
            continue
        bad += [
            (node.lineno, f"imports {m}")
            for m in mods
            if m.split(".")[0] in ("research", "benchmarks")
        ]
    return [f"{script.name}:{line}: {what}" for line, what in sorted(bad)]


@pytest.mark.parametrize("name", [n for n in sorted(QUICK) if (DEMOS / n).is_file()])
def test_demo_imports_only_installed_packages(name):
    """A demo imports the installed packages only: no research code, no ``sys.path``."""
    assert outside_the_package(DEMOS / name) == []


def test_scan_finds_research_and_sys_path(tmp_path):
    """The scan itself: the two ways a demo used to reach the research code are found."""
    script = tmp_path / "demo_x.py"
    script.write_text(
        "import sys\nsys.path.insert(0, 'benchmarks')\n"
        "from research.demos.checks import verify\nimport numpy\n"
    )
    assert outside_the_package(script) == [
        "demo_x.py:2: sys.path",
        "demo_x.py:3: imports research.demos.checks",
    ]
