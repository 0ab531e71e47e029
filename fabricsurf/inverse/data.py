"""Measurement data (DESIGN §6): load, validate and write an experiment directory.

A directory holds ``experiment.toml`` and two CSV files (full-field displacements, grip force).
:func:`load_experiment` converts everything to mm and N and rejects bad input with one
:class:`DataError` whose message names the file, the row (CSV line number, header = line 1)
or key, and the problem. :func:`write_experiment` writes a directory atomically (a temporary
directory, then a rename), so a reader never sees half-written data.

Extension of the contract: the optional ``[data] force_noise_std`` (force units) gives the
noise of the force readings; it weights the force misfit (see :mod:`fabricsurf.inverse.compare`).
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

LENGTH_UNITS = {"mm": 1.0, "m": 1000.0}
FORCE_UNITS = {"N": 1.0, "mN": 1e-3, "kN": 1e3}
CLAMPS = ("gradient", "position")
TESTS = ("tensile",)
FIELD_COLUMNS = ("step", "X", "Y", "ux", "uy")
FORCE_COLUMNS = ("step", "displacement", "force")


class DataError(ValueError):
    """Bad measurement input; the message names file, row or key, and the problem."""


@dataclass
class Experiment:
    """A tensile experiment in mm and N.

    ``steps``, ``displacement``, ``force``: one entry per load step (sorted by step number);
    ``field_step``, ``X`` (n×2), ``u`` (n×2 or n×3): the full-field rows.
    """

    name: str
    length: float
    width: float
    fibre_angles_deg: tuple[float, float]
    clamp: str
    steps: np.ndarray
    displacement: np.ndarray
    force: np.ndarray
    field_step: np.ndarray
    X: np.ndarray
    u: np.ndarray
    noise_std: float | None = None
    force_noise_std: float | None = None
    test: str = "tensile"

    def step_rows(self, step: int) -> np.ndarray:
        """Indices of the field rows of one step."""
        return np.flatnonzero(self.field_step == step)


def _get(table: dict, section: str | None, key: str, where: str = "experiment.toml"):
    t = table if section is None else table.get(section)
    label = f"[{section}] {key}" if section else key
    if not isinstance(t, dict) or key not in t:
        raise DataError(f"{where}: missing key {label}")
    return t[key]


def _number(value, label: str, positive: bool = False) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or (positive and value <= 0):
        need = "a positive finite number" if positive else "a finite number"
        raise DataError(f"experiment.toml: {label} = {value!r} must be {need}")
    return float(value)


def _choice(value, label: str, allowed) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise DataError(f"experiment.toml: {label} = {value!r} is not one of {list(allowed)}")
    return value


def _read_toml(directory: Path) -> dict:
    path = directory / "experiment.toml"
    if not path.is_file():
        raise DataError(f"experiment.toml: file not found in {directory}")
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as e:
        raise DataError(f"experiment.toml: not valid TOML ({e})") from None


def _read_csv(path: Path, columns: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict:
    """Numeric columns of a CSV file; names the line of any empty, non-numeric or NaN cell."""
    name = path.name
    if not path.is_file():
        raise DataError(f"{name}: file not found in {path.parent}")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise DataError(f"{name}: file is empty (expected header {','.join(columns)})")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in columns if c not in header]
    if missing:
        raise DataError(f"{name}: missing column(s) {', '.join(missing)}; header is "
                        f"{','.join(header)}")
    if len(rows) < 2:
        raise DataError(f"{name}: no data rows")
    wanted = list(columns) + [c for c in optional if c in header]
    out = {c: np.empty(len(rows) - 1) for c in wanted}
    for i, row in enumerate(rows[1:]):
        line = i + 2
        if len(row) != len(header):
            raise DataError(f"{name} line {line}: {len(row)} fields, header has {len(header)}")
        for c in wanted:
            cell = row[header.index(c)].strip()
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise DataError(f"{name} line {line}: column {c} = {cell!r} is not a finite "
                                "number")
            out[c][i] = v
    return out


def _steps(values: np.ndarray, name: str) -> np.ndarray:
    bad = np.flatnonzero(values != np.round(values))
    if len(bad):
        raise DataError(f"{name} line {bad[0] + 2}: step {values[bad[0]]!r} is not an integer")
    return values.astype(np.int64)


def _first_duplicate(keys: np.ndarray) -> tuple[int, int] | None:
    """(first row, repeated row) of the first duplicated key row, or None."""
    seen: dict = {}
    for i, k in enumerate(map(tuple, keys)):
        if k in seen:
            return seen[k], i
        seen[k] = i
    return None


def _check_field(f: dict, steps: np.ndarray, length: float, width: float, name: str) -> None:
    tol = 1e-9 * max(length, width)
    X, Y = f["X"], f["Y"]
    out = np.flatnonzero((X < -tol) | (X > length + tol) | (Y < -tol) | (Y > width + tol))
    if len(out):
        i = out[0]
        raise DataError(f"{name} line {i + 2}: point (X, Y) = ({X[i]:g}, {Y[i]:g}) mm is outside "
                        f"the specimen [0, {length:g}] x [0, {width:g}] mm")
    dup = _first_duplicate(np.column_stack([f["step"], X, Y]))
    if dup:
        raise DataError(f"{name} line {dup[1] + 2}: duplicate row (same step, X, Y as line "
                        f"{dup[0] + 2})")
    unknown = np.flatnonzero(~np.isin(f["step"], steps))
    if len(unknown):
        i = unknown[0]
        raise DataError(f"{name} line {i + 2}: step {int(f['step'][i])} does not appear in the "
                        "force file")


def load_experiment(directory: str | Path) -> Experiment:
    """Read, validate and convert (to mm, N) the experiment in ``directory`` (DESIGN §6)."""
    d = Path(directory)
    if not d.is_dir():
        raise DataError(f"{d}: not a directory")
    t = _read_toml(d)
    lu = _choice(_get(t, "units", "length"), "[units] length", LENGTH_UNITS)
    fu = _choice(_get(t, "units", "force"), "[units] force", FORCE_UNITS)
    ls, fs = LENGTH_UNITS[lu], FORCE_UNITS[fu]
    length = _number(_get(t, "specimen", "length"), "[specimen] length", True) * ls
    width = _number(_get(t, "specimen", "width"), "[specimen] width", True) * ls
    angles = _get(t, "specimen", "fibre_angles_deg")
    if not isinstance(angles, list) or len(angles) != 2:
        raise DataError(f"experiment.toml: [specimen] fibre_angles_deg = {angles!r} must be "
                        "a list of two angles")
    angles = tuple(_number(a, "[specimen] fibre_angles_deg", False) for a in angles)
    test = _choice(_get(t, "loading", "test"), "[loading] test", TESTS)
    clamp = _choice(_get(t, "loading", "clamp"), "[loading] clamp", CLAMPS)
    data = t.get("data", {})
    noise = {}
    for key, scale in (("noise_std", ls), ("force_noise_std", fs)):
        noise[key] = (_number(data[key], f"[data] {key}", True) * scale if key in data else None)
    fname, gname = _get(t, "data", "field"), _get(t, "data", "force")
    force = _read_csv(d / str(gname), FORCE_COLUMNS)
    fsteps = _steps(force["step"], str(gname))
    dup = _first_duplicate(fsteps[:, None])
    if dup:
        raise DataError(f"{gname} line {dup[1] + 2}: duplicate step {fsteps[dup[1]]} (also on "
                        f"line {dup[0] + 2})")
    field = _read_csv(d / str(fname), FIELD_COLUMNS, optional=("uz",))
    field["step"] = _steps(field["step"], str(fname))
    field["X"], field["Y"] = field["X"] * ls, field["Y"] * ls
    _check_field(field, fsteps, length, width, str(fname))
    order = np.argsort(fsteps)
    comps = ["ux", "uy"] + (["uz"] if "uz" in field else [])
    return Experiment(
        name=str(t.get("name", d.name)), length=length, width=width, fibre_angles_deg=angles,
        clamp=clamp, steps=fsteps[order], displacement=force["displacement"][order] * ls,
        force=force["force"][order] * fs, field_step=field["step"],
        X=np.column_stack([field["X"], field["Y"]]),
        u=np.column_stack([field[c] for c in comps]) * ls,
        noise_std=noise["noise_std"], force_noise_std=noise["force_noise_std"], test=test)


def _toml_text(exp: Experiment) -> str:
    lines = [f"name = {json.dumps(exp.name)}", "[units]", 'length = "mm"', 'force = "N"',
             "[specimen]",
             f"length = {exp.length!r}", f"width = {exp.width!r}",
             f"fibre_angles_deg = [{exp.fibre_angles_deg[0]!r}, {exp.fibre_angles_deg[1]!r}]",
             "[loading]", f'test = "{exp.test}"', f'clamp = "{exp.clamp}"', "[data]",
             'field = "field.csv"', 'force = "force.csv"']
    for key in ("noise_std", "force_noise_std"):
        if getattr(exp, key) is not None:
            lines.append(f"{key} = {float(getattr(exp, key))!r}")
    return "\n".join(lines) + "\n"


def _write_files(tmp: Path, exp: Experiment) -> None:
    (tmp / "experiment.toml").write_text(_toml_text(exp))
    with open(tmp / "force.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(FORCE_COLUMNS)
        for s, dsp, f in zip(exp.steps, exp.displacement, exp.force):
            w.writerow([int(s), repr(float(dsp)), repr(float(f))])
    comps = ["ux", "uy", "uz"][: exp.u.shape[1]]
    with open(tmp / "field.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["step", "X", "Y", *comps])
        for s, x, u in zip(exp.field_step, exp.X, exp.u):
            w.writerow([int(s), *(repr(float(v)) for v in (*x, *u))])


def write_experiment(directory: str | Path, exp: Experiment, overwrite: bool = False) -> Path:
    """Write ``exp`` (mm, N) as a DESIGN §6 directory, atomically. Call on one rank only."""
    d = Path(directory)
    if d.exists() and not overwrite:
        raise FileExistsError(f"{d}: exists (pass overwrite=True to replace it)")
    d.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{d.name}.", dir=d.parent))
    try:
        _write_files(tmp, exp)
        if d.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{d.name}.old.", dir=d.parent))
            os.replace(d, old / "x")
            os.replace(tmp, d)
            shutil.rmtree(old)
        else:
            os.replace(tmp, d)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return d
