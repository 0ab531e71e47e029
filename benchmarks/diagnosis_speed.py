"""Where a default diagnosis spends its time: forward runs, Newton iterations, factorisations.

Runs ``fabricsurf diagnose DATA --terms fibre_stretch,shear --out …`` (the command line in this
process, with its defaults: the mesh selection of docs/diagnosis.md, ``--confirm 2``,
``--max-effects 2``) on synthetic Hencky-lattice bias-extension data made with the package's
own generator (``inverse/synthetic/generate.py``: ``lattice_data`` + ``add_noise``), and prints,
per mesh level and per stage of the diagnosis, the forward runs, load steps, Newton iterations,
LU factorisations (count and mean time), tangent (sensitivity) solves, the stage's wall time and
its ratio to a *floor*: the Newton iterations the stage needed times the time of one
factorisation of the mesh each ran on, both measured in the same run. A ratio near 1 means the
stage is its factorisations; a large one, that the time goes elsewhere (assembly, tangent
solves, Python, waiting for the other rank, building meshes and forms).

How it measures, without touching the library:

* counts and solver times from PETSc's own event log (``PETSc.Log.begin()``;
  ``MatLUFactorNum``, ``MatLUFactorSym``, ``SNESSolve``, ``KSPSolve``, ``SNESJacobianEval``,
  ``SNESFunctionEval``), read before and after every forward run (``ForwardModel.run``) and
  every tangent solve (the module function ``sensitivities`` of the forward layer);
* stages by wrapping, in this process only, the functions that do them (found by name in the
  loaded ``fabricsurf`` modules, so that modules moved between sub-packages are still found; a
  hook not found is reported and its time counts in its caller's): the single-mesh diagnosis
  (one mesh level), its baseline fit and scan by decades, each ranking round, the candidates'
  refits with their starts (linearised, or the grid on the scout mesh), ties, the h/2 check,
  the builds of meshes and forms, the command's tie separation and outputs; the time a rank
  waits for the other in a shared evaluation (``spread``) is its own row. Times are exclusive
  (a nested stage's time counts for it alone; they add up to the command's wall time) and, as
  all numbers of the tables, rank 0's (``*``: rank 1's counts differ, where the ranks shared
  the trials; every rank's are in the JSON).
* the command's output (the progress messages of the ``fabricsurf`` logger), printed with the
  seconds since the command started (and kept in the JSON), for the stage boundaries as the
  user sees them.

Data (``--cases``, names ``LxW-aANGLE-nROWS-hK[-sSTEPS][-eNOISE]``): a specimen L × W mm,
fibres at ±ANGLE°, about ROWS field rows (every n-th node of one lattice of spacing W/75 per
specimen), 12 steps to 8 % of L, K hidden effects: 1 = geodesic bending (A_g = 40 N·mm,
l_b ≈ 9 mm), 2 = that and shear locking (k4 = 2 N/mm), behind fibre_stretch (k_l = 30 N/mm) +
shear (k_s = 0.5 N/mm); noise NOISE mm (default 0.02) and 2.5 NOISE N. The default family
varies one factor at a time from the default specimen (187 × 119 mm, ±45°, 2·10⁴ rows, one
hidden effect), then all at once, and ends with the default case at half the noise, whose
mesh selection refines (two mesh levels); ``--quick`` runs one small case (48 × 24 mm, 3 steps,
2·10³ rows) in a minute or two. ``--repeat N`` runs each case N times and prints medians;
``--out DIR`` keeps the data (reused), each run's diagnosis and ``diagnosis_speed.json``;
``--report JSON`` prints the tables of a saved profile again; ``--assembly`` times instead one
Jacobian and residual assembly of the baseline, the baseline with one second-gradient term and
the diagnosis's model (every candidate at modulus zero); ``--full-forms`` assembles the full
forms throughout (the path before the first-gradient forms of docs/speed.md, to compare its
answers and times with). Run on 2 ranks (results:
docs/speed.md):

    mpirun -n 2 .venv/bin/python benchmarks/diagnosis_speed.py --quick --out out/speed
    mpirun -n 2 .venv/bin/python benchmarks/diagnosis_speed.py --out out/speed [--repeat 3]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import io
import itertools
import json
import math
import os
import pkgutil
import re
import statistics
import sys
import time
import types
from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import fabricsurf
from fabricsurf.inverse.synthetic import generate as sy

COMM = MPI.COMM_WORLD
BIAS_LENGTH, BIAS_WIDTH = 187.0, 119.0
"""The default specimen of the bias plug-in (geometry/specimen.py, Barchiesi et al. 2020), mm."""
STEPS, STRAIN = 12, 0.08
"""Load steps and the grip displacement at the last one, as a fraction of the length."""
K_L, K_S, A_G, K4 = 30.0, 0.5, 40.0, 2.0
"""The lattice's moduli (continuum equivalents, N/mm and N·mm): fibres, shear, geodesic
bending (hidden), shear locking (hidden in the two-effect cases)."""
SPACING_PER_WIDTH = 1.0 / 75.0
"""Lattice spacing over the specimen's width: about 10⁵ nodes over 12 steps on 187 × 119 mm."""
NOISE_MM, NOISE_N = 0.02, 0.05
BASELINE = "fibre_stretch,shear"
EVENTS = {
    "lu": "MatLUFactorNum",
    "lu_sym": "MatLUFactorSym",
    "snes": "SNESSolve",
    "ksp": "KSPSolve",
    "jacobian": "SNESJacobianEval",
    "residual": "SNESFunctionEval",
}
"""PETSc log events read around every forward run (name here: PETSc's event name)."""
SEP = " › "
"""Between the labels of nested stages."""
WAIT = "waiting (other rank)"


# -- the cases ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Case:
    """One data set of the family (module docstring)."""

    length: float
    width: float
    angle: float
    rows: int
    hidden: int
    steps: int = STEPS
    noise: float = NOISE_MM

    @property
    def name(self) -> str:
        rows = f"{self.rows:.0e}".replace("e+0", "e")
        tail = ("" if self.steps == STEPS else f"-s{self.steps}") + (
            "" if self.noise == NOISE_MM else f"-e{self.noise:g}"
        )
        return f"{self.length:g}x{self.width:g}-a{self.angle:g}-n{rows}-h{self.hidden}{tail}"

    @classmethod
    def parse(cls, name: str) -> Case:
        """The case a name of the module docstring's form describes."""
        num = r"(\d+(?:\.\d+)?)"
        m = re.fullmatch(rf"{num}x{num}-a{num}-n([0-9.e+]+)-h([12])(?:-s(\d+))?(?:-e{num})?", name)
        if m is None:
            raise SystemExit(
                f"--cases: {name!r} is not LxW-aANGLE-nROWS-hK[-sSTEPS][-eNOISE], "
                "e.g. 187x119-a45-n2e4-h1"
            )
        L, W, a, n, k, s, e = m.groups()
        return cls(
            float(L),
            float(W),
            float(a),
            int(float(n)),
            int(k),
            int(s or STEPS),
            float(e or NOISE_MM),
        )

    def hidden_moduli(self) -> dict:
        """The hidden effects' lattice moduli (keywords of ``lattice_data``)."""
        return {"A_g": A_G, "k4": K4 if self.hidden >= 2 else 0.0}


DEFAULT = Case(BIAS_LENGTH, BIAS_WIDTH, 45.0, 20_000, 1)
FAMILY = [
    DEFAULT,
    Case(100.0, 50.0, 45.0, 20_000, 1),
    Case(BIAS_LENGTH, BIAS_WIDTH, 40.0, 20_000, 1),
    Case(BIAS_LENGTH, BIAS_WIDTH, 45.0, 100_000, 1),
    Case(BIAS_LENGTH, BIAS_WIDTH, 45.0, 20_000, 2),
    Case(100.0, 50.0, 40.0, 100_000, 2),
    Case(BIAS_LENGTH, BIAS_WIDTH, 45.0, 20_000, 1, noise=0.01),
]
"""The default family: one factor at a time from the default specimen, then all at once, and
the default case at half the noise (its h/2 check asks for a finer mesh: two mesh levels)."""
QUICK = Case(48.0, 24.0, 45.0, 2_000, 1, steps=3)


def lattice_experiment(case: Case):
    """The case's noisy lattice data: the lattice solved once per specimen and angle, every
    n-th node measured so that the field has about ``case.rows`` rows."""
    L, W = case.length, case.width
    path = list(np.linspace(STRAIN * L / case.steps, STRAIN * L, case.steps))
    spacing = SPACING_PER_WIDTH * W
    nodes = L * W / spacing**2 * math.sin(math.radians(2 * case.angle))
    every = max(1, round(nodes * case.steps / case.rows))
    exp = sy.template(
        L, W, path, np.zeros((0, 2)), angles=(case.angle, -case.angle), name=f"lattice_{case.name}"
    )
    sy.lattice_data(exp, spacing, k_l=K_L, k_s=K_S, every=every, **case.hidden_moduli())
    return sy.add_noise(exp, case.noise, NOISE_N * case.noise / NOISE_MM, seed=2024)


def make_data(case: Case, root: Path) -> tuple[Path, float]:
    """The case's data directory (made on rank 0 unless already there) and the seconds spent."""
    d = root / "data" / case.name
    t0, err = time.perf_counter(), None
    if COMM.rank == 0 and not (d / "experiment.toml").is_file():
        try:
            fabricsurf.write_experiment(d, lattice_experiment(case), overwrite=True)
        except Exception as e:  # raised on every rank below
            err = f"{type(e).__name__}: {e}"
    err = COMM.bcast(err)
    if err:
        raise RuntimeError(f"data of {case.name}: {err}")
    return d, COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX)


# -- measuring ------------------------------------------------------------------------------
def counters() -> dict[str, tuple[int, float]]:
    """(count, seconds) of every event of :data:`EVENTS` so far on this rank."""
    out = {}
    for key, name in EVENTS.items():
        info = PETSc.Log.Event(name).getPerfInfo()
        out[key] = (int(info["count"]), float(info["time"]))
    return out


@dataclass
class Frame:
    """A stage being timed: ``key`` gets its exclusive time, ``base`` is its children's
    parent path (differs for the wait of a shared evaluation and for pass-through frames)."""

    key: tuple
    base: tuple
    start: float
    cpu: float
    nested: float = 0.0
    nested_cpu: float = 0.0


@dataclass
class Profile:
    """Exclusive wall and CPU seconds per stage path, and one record per forward run."""

    own: dict = field(default_factory=lambda: defaultdict(float))
    cpu: dict = field(default_factory=lambda: defaultdict(float))
    runs: list = field(default_factory=list)
    stack: list = field(default_factory=list)
    order: dict = field(default_factory=dict)
    """Stage path → the order in which the stages were first entered (the tables' order)."""
    level: int = -1
    rounds: int = 0
    tangent: list = field(default_factory=lambda: [0, 0.0, 0.0])
    """Tangent solves (KSPSolve calls), their KSPSolve seconds, the sensitivities' seconds."""

    def base(self) -> tuple:
        return self.stack[-1].base if self.stack else ()

    @contextlib.contextmanager
    def frame(self, label: str | None, kind: str = "stage") -> Iterator[None]:
        """Time a stage ``label`` nested in the current one; ``kind`` "wait": its own time is
        a row of its own but its children stay in the parent's stage; "through": no stage
        (its time is the parent's, its children too)."""
        parent = self.base()
        key = parent + (label,) if kind in ("stage", "wait") else parent
        base = key if kind == "stage" else parent
        f = Frame(key, base, time.perf_counter(), time.process_time())
        self.order.setdefault(key, len(self.order))
        self.stack.append(f)
        try:
            yield
        finally:
            self.stack.pop()
            dt, dc = time.perf_counter() - f.start, time.process_time() - f.cpu
            self.own[f.key] += dt - f.nested
            self.cpu[f.key] += dc - f.nested_cpu
            if self.stack:
                self.stack[-1].nested += dt
                self.stack[-1].nested_cpu += dc

    def in_stage(self, label: str) -> bool:
        return label in self.base()


PROFILE = Profile()


def record_run(model, sens, run: Callable[[], object]):
    """``run()`` (one forward run of ``model``) with its PETSc counts, Newton iterations, load
    steps and tangent solves appended to :data:`PROFILE`."""
    c0, t0, tan0 = counters(), time.perf_counter(), list(PROFILE.tangent)
    pred, failed = None, True
    try:
        pred = run()
        failed = False
        return pred
    finally:
        c1 = counters()
        mesh = model.mesh()
        delta = {k: (c1[k][0] - c0[k][0], c1[k][1] - c0[k][1]) for k in EVENTS}
        newton = getattr(pred, "newton", None)
        PROFILE.runs.append(
            {
                "key": list(PROFILE.base()),
                "level": PROFILE.level,
                "h": model.h,
                "dofs": mesh["dofs"],
                "cells": mesh["cells"],
                "local": bool(model.local),
                "steps": len(model.exp.path),
                "sens_params": len(model.params) if sens is True else len(sens or []),
                "newton": delta["jacobian"][0] if newton is None else int(newton),
                "failed": failed,
                "wall": time.perf_counter() - t0,
                "tangent_solves": PROFILE.tangent[0] - tan0[0],
                "tangent_ksp_s": PROFILE.tangent[1] - tan0[1],
                "tangent_s": PROFILE.tangent[2] - tan0[2],
                **{f"{k}_n": v[0] for k, v in delta.items()},
                **{f"{k}_s": v[1] for k, v in delta.items()},
            }
        )


# -- hooks: the stages, found by name in the loaded package ---------------------------------
def load_package() -> None:
    """Import every module of the inverse layer and the command line, wherever they now are
    (so that the hooks below find the functions whatever sub-package holds them)."""
    for pkg in ("fabricsurf.inverse", "fabricsurf.cli"):
        root = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(root.__path__, pkg + "."):
            with contextlib.suppress(Exception):  # a module mid-move: its hooks are reported
                importlib.import_module(info.name)


def _modules() -> list[types.ModuleType]:
    return [
        m
        for name, m in list(sys.modules.items())
        if name.startswith("fabricsurf") and isinstance(m, types.ModuleType)
    ]


def defined(name: str) -> list:
    """Every function or class ``name`` defined at module level in a loaded fabricsurf module
    (a name defined in several modules, e.g. a private helper of two sub-packages, gives all;
    each is wrapped, and only the one the diagnosis calls is ever timed)."""
    return [
        m.__dict__[name]
        for m in _modules()
        if getattr(m.__dict__.get(name), "__module__", None) == m.__name__
    ]


def replace_everywhere(old: object, new: object) -> None:
    """Every module-level reference to ``old`` in the package now names ``new``."""
    for m in _modules():
        for attr, value in list(m.__dict__.items()):
            if value is old:
                setattr(m, attr, new)


def staged(label: str | Callable[[], str], kind: str = "stage"):
    """A decorator timing the function as stage ``label`` (a string, or a function giving
    one at the call)."""

    def wrap(fn):
        @functools.wraps(fn)
        def timed(*a, **k):
            with PROFILE.frame(label() if callable(label) else label, kind):
                return fn(*a, **k)

        return timed

    return wrap


def _level_label() -> str:
    PROFILE.level += 1
    PROFILE.rounds = 0
    return f"level {PROFILE.level}"


def _round_label() -> str:
    PROFILE.rounds += 1
    return f"round {PROFILE.rounds}"


def _shared(fn):
    """``spread(fm, items, evaluate)``: this rank's own evaluations count in the caller's
    stage, the rest of the call (the gather: waiting for the other rank) is a row."""

    @functools.wraps(fn)
    def timed(fm, items, evaluate, *a, **k):
        def mine(x):
            with PROFILE.frame(None, "through"):
                return evaluate(x)

        with PROFILE.frame(WAIT, "wait"):
            return fn(fm, items, mine, *a, **k)

    return timed


def _counted_run(fn):
    @functools.wraps(fn)
    def run(model, sens=False, *a, **k):
        return record_run(model, sens, lambda: fn(model, sens, *a, **k))

    return run


def _tangent(fn):
    @functools.wraps(fn)
    def solves(*a, **k):
        c0, t0 = PETSc.Log.Event("KSPSolve").getPerfInfo(), time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            c1 = PETSc.Log.Event("KSPSolve").getPerfInfo()
            PROFILE.tangent[0] += int(c1["count"] - c0["count"])
            PROFILE.tangent[1] += float(c1["time"] - c0["time"])
            PROFILE.tangent[2] += time.perf_counter() - t0

    return solves


def _build_label() -> str | None:
    return None if PROFILE.base()[-1:] == ("build",) else "build"


def _built(fn):
    """A constructor of forward models: stage "build" (meshes, forms, locators), once."""

    @functools.wraps(fn)
    def init(self, *a, **k):
        label = _build_label()
        with PROFILE.frame(label, "stage" if label else "through"):
            return fn(self, *a, **k)

    return init


FUNCTION_HOOKS: list[tuple[str, Callable]] = [
    ("diagnose", staged(_level_label)),
    ("fit", staged(lambda: "LM fit" if PROFILE.in_stage("refits") else "baseline fit")),
    ("scan_terms", staged("scan (scout)")),
    ("rank_round", staged(_round_label)),
    ("_refit", staged("refits")),
    ("candidate_start", staged("starts (scout grid)")),
    ("grid_start", staged("starts (scout grid)")),
    ("linearised_start", staged("starts (linearised)")),
    ("find_tie", staged("ties")),
    ("spread", _shared),
    ("sensitivities", _tangent),
    ("separate_tie", staged("tie separation")),
    ("write_comparison", staged("outputs (figures, CSV)")),
    ("misfit_path", staged("outputs (figures, CSV)")),
]
"""Module-level functions wrapped wherever they are defined (module docstring); for
``diagnose`` and ``fit`` the root's ``fabricsurf.diagnose`` and ``fabricsurf.fit``."""
METHOD_HOOKS: list[tuple[str, str, Callable]] = [
    ("ForwardModel", "run", _counted_run),
    ("ForwardModel", "__init__", _built),
    ("ForwardSet", "__init__", _built),
    ("FitResult", "check_mesh", staged("h/2 check")),
]


def install() -> list[str]:
    """Wrap every hook; returns the hooks not found in this tree."""
    load_package()
    missing = []
    roots = {"diagnose": [fabricsurf.diagnose], "fit": [fabricsurf.fit]}
    for name, wrapper in FUNCTION_HOOKS:
        found = roots.get(name) or defined(name)
        if not found:
            missing.append(name)
        for fn in found:
            replace_everywhere(fn, wrapper(fn))
    for cls_name, attr, wrapper in METHOD_HOOKS:
        found = [getattr(fabricsurf, cls_name, None)] if hasattr(fabricsurf, cls_name) else []
        for cls in found or defined(cls_name):
            setattr(cls, attr, wrapper(getattr(cls, attr)))
        if not (found or defined(cls_name)):
            missing.append(f"{cls_name}.{attr}")
    return missing


class Stamped(io.TextIOBase):
    """Standard output while the command runs: each line printed with the seconds since the
    start and kept (the timeline in the JSON). The package's progress messages reach it through
    whatever handler the command line configured (they are written to the current
    ``sys.stdout``)."""

    def __init__(self, out) -> None:
        super().__init__()
        self.out, self.t0, self.lines, self.part = out, time.perf_counter(), [], ""

    def write(self, text: str) -> int:
        self.part += text
        while "\n" in self.part:
            line, self.part = self.part.split("\n", 1)
            t = time.perf_counter() - self.t0
            self.lines.append([round(t, 3), line])
            self.out.write(f"  [{t:8.1f} s] {line}\n")
        self.out.flush()
        return len(text)

    def flush(self) -> None:
        self.out.flush()


# -- one diagnosis --------------------------------------------------------------------------
def diagnose_once(data: Path, out: Path, extra: list[str]) -> dict:
    """The command once under the hooks: status, wall seconds, per-rank profiles, the
    diagnosis's JSON (rank 0) and the timeline of its messages."""
    from fabricsurf.cli import main

    PROFILE.__init__()
    stamped = Stamped(sys.stdout)
    argv = ["diagnose", str(data), "--terms", BASELINE, "--out", str(out), *extra]
    COMM.barrier()
    load = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    with PROFILE.frame(None, "through"), contextlib.redirect_stdout(stamped):
        status = main(argv)
    wall = COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    cpu = COMM.gather(time.process_time() - c0)
    mine = {
        "own": {SEP.join(k): v for k, v in PROFILE.own.items()},
        "cpu": {SEP.join(k): v for k, v in PROFILE.cpu.items()},
        "order": [SEP.join(k) for k in PROFILE.order],
        "runs": PROFILE.runs,
    }
    ranks = COMM.gather(mine)
    result = None
    if COMM.rank == 0 and (out / "diagnosis.json").is_file():
        result = json.loads((out / "diagnosis.json").read_text())
    return {
        "status": status,
        "seconds": wall,
        "cpu_seconds": cpu,
        "load_before": load,
        "load_after": os.getloadavg()[0],
        "ranks": ranks,
        "diagnosis": result,
        "timeline": stamped.lines,
    }


# -- tables ---------------------------------------------------------------------------------
SUMMED = (
    "newton",
    "snes_n",
    "lu_n",
    "lu_s",
    "lu_sym_n",
    "lu_sym_s",
    "jacobian_n",
    "jacobian_s",
    "residual_s",
    "tangent_solves",
    "tangent_ksp_s",
    "tangent_s",
)
"""Per-run numbers summed over a stage's runs."""
COLUMNS = ("runs", "steps", *SUMMED, "run_s", "floor_s", "wall", "cpu")


def mesh_key(run: dict) -> tuple:
    """A run's mesh: (level, unknowns, rank-local); the level too, because the load of a
    shared machine changes between levels, and a finer level's fit mesh is the coarser one's
    h/2 check."""
    return run["level"], run["dofs"], run["local"]


def lu_means(runs: list[dict]) -> dict[tuple, float]:
    """Mean seconds of one numeric factorisation per mesh (:func:`mesh_key`)."""
    n: dict = defaultdict(int)
    s: dict = defaultdict(float)
    for r in runs:
        m = mesh_key(r)
        n[m] += r["lu_n"]
        s[m] += r["lu_s"]
    return {m: s[m] / n[m] for m in n if n[m]}


def empty() -> dict:
    return dict.fromkeys(COLUMNS, 0.0)


def stage_rows(rank: dict) -> dict[str, dict]:
    """One rank's stages: exclusive wall and CPU seconds and the sums over their runs; the
    floor of a run is its Newton iterations times one factorisation of its mesh."""
    means = lu_means(rank["runs"])
    rows = {
        k: empty() | {"wall": rank["own"].get(k, 0.0), "cpu": rank["cpu"].get(k, 0.0)}
        for k in rank["order"]
    }
    for r in rank["runs"]:
        q = rows.setdefault(SEP.join(r["key"]), empty())
        q["runs"] += 1
        q["steps"] += r["steps"]
        q["run_s"] += r["wall"]
        q["floor_s"] += r["newton"] * means.get(mesh_key(r), 0.0)
        for c in SUMMED:
            q[c] += r[c]
    return rows


def combined(ranks: list[dict]) -> dict[str, dict]:
    """The ranks' stages as rank 0 saw them (its exclusive times add up to its wall time; the
    time it waited for another rank's share of a shared evaluation is a row of its own), with
    ``differs`` where another rank's runs or Newton iterations in the stage were not rank 0's
    (the ranks run the same computation except where they share trials)."""
    per = [stage_rows(r) for r in ranks]
    out = {}
    for key in dict.fromkeys(k for p in per for k in p):
        rows = [p.get(key, empty()) for p in per]
        q = dict(rows[0])
        q["differs"] = any(
            (r["newton"], r["runs"]) != (rows[0]["newton"], rows[0]["runs"]) for r in rows[1:]
        )
        out[key] = q
    return out


def median_rows(repeats: list[dict[str, dict]]) -> dict[str, dict]:
    """Each stage's numbers as the median over the repeats (a stage missing from one: 0)."""
    out = {}
    for k in dict.fromkeys(k for r in repeats for k in r):
        rows = [r.get(k) or empty() for r in repeats]
        out[k] = {c: statistics.median(r[c] for r in rows) for c in COLUMNS}
        out[k]["differs"] = any(r.get("differs") for r in rows)
    return out


def level_of(key: str) -> tuple[int | None, str]:
    """(mesh level or None, the stage's name within it)."""
    parts = key.split(SEP) if key else []
    if parts and parts[0].startswith("level "):
        name = SEP.join(parts[1:]) or "rest of the level (statistics, reports)"
        return int(parts[0].split()[1]), name + (
            " ranking" if re.fullmatch(r"round \d+", name) else ""
        )
    return None, SEP.join(parts) or "command (reading, checks, JSON)"


def say(*lines: str) -> None:
    if COMM.rank == 0:
        print("\n".join(lines), flush=True)


WIDTH = 50
HEAD = (
    f"  {'stage':{WIDTH + 1}s}{'runs':>5s} {'steps':>6s} {'Newton':>7s} {'LU n':>6s} "
    f"{'LU ms':>8s} {'sym n':>5s} {'tang.':>6s} {'wall s':>8s} {'floor s':>8s} {'×floor':>7s}"
)
HEAD_INSIDE = (
    f"  {'stage':{WIDTH}s} {'runs s':>7s} {'LU num':>7s} {'LU sym':>7s} "
    f"{'Jacob.':>7s} {'resid.':>7s} {'tangent':>7s} {'(KSP)':>7s} {'rest':>7s} "
    f"{'outside':>7s} {'CPU s':>7s}"
)


def fmt_row(name: str, q: dict) -> str:
    lu_ms = 1e3 * q["lu_s"] / q["lu_n"] if q["lu_n"] else 0.0
    ratio = f"{q['wall'] / q['floor_s']:7.1f}" if q["floor_s"] > 0 else f"{'–':>7s}"
    star = "*" if q.get("differs") else " "
    return (
        f"  {name[:WIDTH]:{WIDTH}s}{star}{q['runs']:5.0f} {q['steps']:6.0f} "
        f"{q['newton']:7.0f} {q['lu_n']:6.0f} {lu_ms:8.2f} {q['lu_sym_n']:5.0f} "
        f"{q['tangent_solves']:6.0f} {q['wall']:8.2f} {q['floor_s']:8.2f} {ratio}"
    )


def fmt_inside(name: str, q: dict) -> str:
    rest = (
        q["run_s"] - q["lu_s"] - q["lu_sym_s"] - q["jacobian_s"] - q["residual_s"] - q["tangent_s"]
    )
    return (
        f"  {name[:WIDTH]:{WIDTH}s} {q['run_s']:7.2f} {q['lu_s']:7.2f} {q['lu_sym_s']:7.2f} "
        f"{q['jacobian_s']:7.2f} {q['residual_s']:7.2f} {q['tangent_s']:7.2f} "
        f"{q['tangent_ksp_s']:7.2f} {rest:7.2f} {q['wall'] - q['run_s']:7.2f} "
        f"{q['cpu']:7.2f}"
    )


def total(rows: list[dict]) -> dict:
    return {c: sum(r[c] for r in rows) for c in COLUMNS} | {"differs": False}


def shown(q: dict) -> bool:
    """A stage worth a row: it ran something or took at least 5 ms."""
    return q["runs"] > 0 or q["wall"] >= 0.005


def _level_line(lev: int, levels: list[dict]) -> str:
    q = levels[lev] if lev < len(levels) else {}
    g = lambda x: "–" if x is None else f"{x:.4g}"  # noqa: E731
    return (
        f"   level {lev}: h = {', '.join(f'{x:.4g}' for x in q.get('h', []))} mm, "
        f"{q.get('dofs', 0):,} unknowns, {q.get('seconds', 0):.1f} s; h/2 check chi2_h "
        f"{g(q.get('chi2_h'))} against the band {g(q.get('noise_band'))} (too coarse: "
        f"{q.get('too_coarse')}); verdict {q.get('verdict')}, terms "
        f"{'+'.join(q.get('terms', []))}"
    )


def print_case(
    case: Case, rows: dict[str, dict], runs: list[dict], rep: dict, n_repeat: int
) -> None:
    """The tables of one case (module docstring), from rank 0."""
    d = rep.get("diagnosis") or {}
    ms = (d.get("discretisation") or {}).get("mesh_selection") or {}
    tot = total(list(rows.values()))
    say(
        "",
        f"== {case.name}: {'median of ' + str(n_repeat) + ' runs' if n_repeat > 1 else '1 run'}"
        f"; status {rep['status']}; wall {rep['seconds']:.1f} s, floor {tot['floor_s']:.2f} s "
        f"(×{tot['wall'] / max(tot['floor_s'], 1e-9):.1f}); CPU s per rank "
        f"{', '.join(f'{c:.1f}' for c in rep['cpu_seconds'])}; load {rep['load_before']:.1f} → "
        f"{rep['load_after']:.1f}",
        f"   verdict {d.get('verdict')}, adequate {d.get('adequate')}, terms "
        f"{'+'.join((d.get('final') or {}).get('terms', []))}; {d.get('outcome')}; "
        f"refinement stopped by: {ms.get('stopped')}",
    )
    for m, t in sorted(lu_means(runs).items()):
        n = sum(r["lu_n"] for r in runs if mesh_key(r) == m)
        say(
            f"   level {m[0]}, mesh of {m[1]:,} unknowns ({'rank-local' if m[2] else 'distributed'}"
            f"): {n} factorisations (rank 0), one {1e3 * t:.2f} ms"
        )
    by_level: dict = defaultdict(list)
    for k, q in rows.items():
        if shown(q):
            by_level[level_of(k)[0]].append((level_of(k)[1], q))
    order = sorted(by_level, key=lambda x: (x is None, x or 0))
    for lev in order:  # the level's or the command's own rest last
        by_level[lev].sort(key=lambda nq: nq[0].startswith(("rest of", "command (")))
    for lev in order:
        say(
            "",
            "   outside the mesh levels:"
            if lev is None
            else _level_line(lev, ms.get("levels", [])),
        )
        say(
            HEAD,
            *(fmt_row(n, q) for n, q in by_level[lev]),
            fmt_row("total", total([q for _, q in by_level[lev]])),
        )
    say(
        "",
        "   inside the stages (s): the runs; in them the numeric and symbolic factorisations, "
        "Jacobian and residual assemblies, the tangent sensitivities (their KSP solves), the "
        "rest; outside the runs; CPU",
        HEAD_INSIDE,
        *(
            fmt_inside(n if lev is None else f"L{lev} {n}", q)
            for lev in order
            for n, q in by_level[lev]
        ),
        fmt_inside("total", tot),
    )


# -- main -----------------------------------------------------------------------------------
def run_case(case: Case, root: Path, repeat: int, extra: list[str]) -> dict:
    """Make the data, diagnose ``repeat`` times; the JSON record (rank 0; {} elsewhere)."""
    data, made = make_data(case, root)
    say("", f"## {case.name}: data {data} ({made:.1f} s to make)")
    reps = []
    for k in range(repeat):
        say(f"# {case.name}, run {k + 1}/{repeat}")
        reps.append(diagnose_once(data, root / "runs" / case.name / f"r{k}", extra))
    if COMM.rank != 0:
        return {}
    exp = fabricsurf.load_experiment(data)
    return {
        "case": case.__dict__ | {"name": case.name},
        "data": str(data),
        "field_rows": len(exp.X),
        "steps": len(exp.steps),
        "data_seconds": made,
        "repeats": reps,
    }


def case_rows(record: dict) -> tuple[dict[str, dict], dict]:
    """A case's stages (medians over its repeats) and the repeat of median wall time."""
    reps = record["repeats"]
    per = [combined(r["ranks"]) for r in reps]
    mid = sorted(range(len(reps)), key=lambda i: reps[i]["seconds"])[len(reps) // 2]
    return (median_rows(per) if len(per) > 1 else per[0]), reps[mid]


def report_case(record: dict) -> None:
    """The tables of one case (rank 0)."""
    rows, rep = case_rows(record)
    n = len(record["repeats"])
    print_case(
        Case(**{k: v for k, v in record["case"].items() if k != "name"}),
        rows,
        rep["ranks"][0]["runs"],
        rep | {"seconds": statistics.median(r["seconds"] for r in record["repeats"])},
        n,
    )


GROUPS = (
    ("baseline", "baseline fit"),
    ("ranking", " ranking"),
    ("refit starts", "starts ("),
    ("refit LM", "refits › LM fit"),
    ("h/2 check", "h/2 check"),
    ("waiting", "waiting"),
)
"""Summary columns: share of the wall time in stages whose name contains the pattern (the
first that matches; the rest: builds, ties, outputs, the command's own)."""


def group_of(name: str) -> str:
    return next((g for g, pattern in GROUPS if pattern in name), "other")


def summary(results: dict) -> None:
    """One line per case: totals, the floor, and where the wall time went (percent)."""
    say(
        "",
        "## summary (rank 0's stages; CPU s: the busier rank's)",
        "| case | rows | levels (unknowns) | wall s | CPU s | runs | Newton | LU | floor s | "
        "×floor | Newton on the scout | " + " | ".join(g for g, _ in GROUPS) + " | other |",
        "|" + "---|" * (12 + len(GROUPS)),
    )
    for record in results["cases"]:
        if not record:
            continue
        rows, rep = case_rows(record)
        named = [(level_of(k)[1], q) for k, q in rows.items()]
        tot = total([q for _, q in named])
        share = defaultdict(float)
        for name, q in named:
            share[group_of(name)] += q["wall"]
        scout = sum(q["newton"] for name, q in named if "(scout" in name)
        ms = ((rep.get("diagnosis") or {}).get("discretisation") or {}).get("mesh_selection") or {}
        levels = ", ".join(f"{q['dofs']:,}" for q in ms.get("levels", []))
        say(
            f"| {record['case']['name']} | {record['field_rows']:,} | {levels} | "
            f"{tot['wall']:.1f} | {max(rep['cpu_seconds']):.1f} | {tot['runs']:.0f} | "
            f"{tot['newton']:.0f} | {tot['lu_n']:.0f} | {tot['floor_s']:.1f} | "
            f"{tot['wall'] / max(tot['floor_s'], 1e-9):.1f} | "
            f"{100 * scout / max(tot['newton'], 1):.0f} % | "
            + " | ".join(
                f"{100 * share[g] / tot['wall']:.0f} %" for g, _ in (*GROUPS, ("other", ""))
            )
            + " |"
        )


def assembly_times(data: Path, repeat: int = 20) -> None:
    """Seconds of one Jacobian assembly (into the existing matrix, and into a new one as the
    tangent solves do) and one residual assembly at the converged last step, serially at the
    test's default mesh, of the baseline model, of the baseline with one second-gradient
    candidate (what a refit needs) and of the diagnosis's model (the baseline with every visible
    candidate at modulus zero, one form): what the candidates at zero cost every Newton
    iteration. Rank 0 only."""
    from dolfinx.fem import petsc as fem_petsc

    full_model = defined("full_model")[0]
    exp = fabricsurf.load_experiment(data)
    base = BASELINE.split(",")
    for label, model in (
        ("baseline", [fabricsurf.make_term(n) for n in base]),
        (
            "baseline + geodesic_bending",
            [fabricsurf.make_term(n) for n in [*base, "geodesic_bending"]],
        ),
        ("diagnosis (candidates at 0)", full_model(base)),
    ):
        with fabricsurf.ForwardModel(exp, model, comm=MPI.COMM_SELF) as fm:
            fm.run()
            s = fm.test.solver
            A = fem_petsc.assemble_matrix(s.a)
            A.assemble()
            t = [time.perf_counter()]
            for _ in range(repeat):
                A.zeroEntries()
                fem_petsc.assemble_matrix(A, s.a)
                A.assemble()
            t.append(time.perf_counter())
            for _ in range(repeat):
                fem_petsc.assemble_matrix(s.a).destroy()
            t.append(time.perf_counter())
            for _ in range(repeat):
                s.internal_force()
            t.append(time.perf_counter())
            A.destroy()
            ms = [1e3 * (b - a) / repeat for a, b in itertools.pairwise(t)]
            say(
                f"   {label} ({len(model)} terms, {fm.mesh()['dofs']:,} unknowns): Jacobian "
                f"{ms[0]:.1f} ms (into a new matrix {ms[1]:.1f} ms), residual {ms[2]:.1f} ms"
            )


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("out/diagnosis_speed"))
    ap.add_argument("--quick", action="store_true", help=f"one small case ({QUICK.name})")
    ap.add_argument(
        "--cases",
        default=None,
        help="comma-separated case names (default: the family: "
        + ",".join(c.name for c in FAMILY)
        + ")",
    )
    ap.add_argument("--repeat", type=int, default=1, help="runs per case (medians printed)")
    ap.add_argument(
        "--diagnose-args",
        default="",
        help="further options of diagnose, e.g. '--time-budget 600' (default: none, the "
        "command's defaults)",
    )
    ap.add_argument(
        "--report",
        type=Path,
        default=None,
        help="print the tables of a saved diagnosis_speed.json and stop (nothing is run)",
    )
    ap.add_argument(
        "--full-forms",
        action="store_true",
        help="assemble the full forms even while every second-gradient modulus is zero (the "
        "path before the first-gradient forms; default: off)",
    )
    ap.add_argument(
        "--assembly",
        action="store_true",
        help="instead: time one Jacobian and residual assembly of the baseline and of the "
        "diagnosis's model (candidates at zero) on each case's data, serially",
    )
    return ap.parse_args()


def run_assembly(cases: list[Case], root: Path) -> None:
    """``--assembly``: :func:`assembly_times` on each case's data."""
    load_package()
    for case in cases:
        data, _ = make_data(case, root)
        say(f"## {case.name}: one assembly (serial, load {os.getloadavg()[0]:.1f})")
        if COMM.rank == 0:
            assembly_times(data)
        COMM.barrier()


def report_file(path: Path) -> None:
    """``--report``: the tables of a saved profile."""
    results = json.loads(path.read_text())
    for record in results["cases"]:
        if record:
            report_case(record)
    summary(results)


def run_family(cases: list[Case], root: Path, repeat: int, extra: list[str]) -> None:
    """Profile every case, printing its tables and rewriting the JSON after each."""
    PETSc.Log.begin()
    missing = install()
    say(
        f"{COMM.size} ranks, {os.cpu_count()} cores, {time.strftime('%Y-%m-%d %H:%M')}; cases "
        + ", ".join(c.name for c in cases)
    )
    if missing:
        say(f"hooks not found (their time counts in their callers'): {', '.join(missing)}")
    results = {
        "ranks": COMM.size,
        "cores": os.cpu_count(),
        "date": time.strftime("%Y-%m-%d"),
        "missing_hooks": missing,
        "cases": [],
    }
    for case in cases:
        results["cases"].append(run_case(case, root, repeat, extra))
        if COMM.rank == 0:
            report_case(results["cases"][-1])
            (root / "diagnosis_speed.json").write_text(json.dumps(results, indent=1, default=str))
    if COMM.rank == 0:
        summary(results)


def main() -> None:
    args = parse_args()
    if args.report is not None:
        report_file(args.report)
        return
    named = [Case.parse(n) for n in args.cases.split(",")] if args.cases else FAMILY
    cases = [QUICK] if args.quick else named
    if args.full_forms:  # the slow path: never the first-gradient forms
        import fabricsurf.discretise.problem as problem

        problem.second_gradient_off = lambda model: False
    if args.assembly:
        run_assembly(cases, args.out)
    else:
        run_family(cases, args.out, args.repeat, args.diagnose_args.split())


if __name__ == "__main__":
    main()
