"""Every demo runs in its quick mode as a user runs it, under ``mpirun -n 2`` in a process of
its own, and passes its own checks; then its summary.json meets the checks the demo declares
(its module-level ``CHECKS``, read from the source: research.demos.checks) and its output holds
no compiler message.

A process of its own: the demos do not share the PETSc options database, the JIT state or the
memory of the pytest session. These tests start their own ranks, so they run in the serial
session only and skip in the 2-rank one. dolfinx runs its demos on 1 rank as well; here the
1-rank physics of each demo is the library's, asserted by its own tests (test_bias_extension,
test_diagnose*, test_dispersion, test_hypar, test_hemisphere), and 1 = 2 ranks by
test_parallel and test_hemisphere, so a serial demo run would repeat them at minutes of cost.

The woven-fabric and bending demos take minutes even in quick mode (a 43-step force curve with
a full diagnosis; 3D strips), the DIC demo about two (its diagnosis; its import is
tests/test_dic.py's): they run only with FABRICSURF_ALL_DEMOS=1, to keep the suite
within its time budget (the skip is reported by pytest -ra)."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from mpi4py import MPI

from research.demos.checks import declared, failures

DEMOS = Path(__file__).resolve().parents[1] / "demos"
QUICK = {
    "demo_hypar.py": ["--quick"],
    "demo_dispersion.py": ["--quick"],
    "demo_hidden_effect.py": ["--quick"],
    "demo_bias_extension.py": ["--quick"],
    "demo_bending.py": ["--quick"],
    "demo_woven_fabric.py": ["--quick"],
    "demo_forming.py": ["--quick"],
    "demo_dic.py": [],
}
SLOW = {"demo_bending.py", "demo_woven_fabric.py", "demo_dic.py"}
RANKS = 2
# what FFCx, UFL and cffi/distutils print while compiling a form
COMPILER = re.compile(r"^(INFO:|DEBUG:|.*\bgcc\b|.*\bcc1\b|running build_ext|building '|"
                      r"Compiling form|Compiler stage)", re.M)
ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
       "OMPI_MCA_rmaps_base_oversubscribe": "1", "OMP_NUM_THREADS": "1",
       "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


def run_demo(name: str, out: Path) -> str:
    """Run the demo in quick mode on RANKS ranks; its output (stdout and stderr)."""
    cmd = ["mpirun", "-n", str(RANKS), sys.executable, str(DEMOS / name), "--out", str(out),
           *QUICK[name]]
    p = subprocess.run(cmd, env=dict(os.environ, **ENV), capture_output=True, text=True,
                       timeout=1800)
    text = p.stdout + p.stderr
    assert p.returncode == 0, f"{' '.join(cmd)} exited {p.returncode}:\n{text[-4000:]}"
    return text


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                    reason="starts its own ranks from the serial session")
@pytest.mark.parametrize("name", [n for n in sorted(QUICK) if (DEMOS / n).is_file()])
def test_demo_runs_and_meets_its_checks(name, tmp_path):
    if name in SLOW and not os.environ.get("FABRICSURF_ALL_DEMOS"):
        pytest.skip(f"{name}: minutes even in quick mode; FABRICSURF_ALL_DEMOS=1 runs it")
    checks = declared(DEMOS / name)
    assert checks, f"{name} declares no checks"
    text = run_demo(name, tmp_path / "out")
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
