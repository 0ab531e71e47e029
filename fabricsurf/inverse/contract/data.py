"""Measurement data, contract version 2 (docs/contracts.md): load, validate, write a directory.

A directory holds ``experiment.toml`` and at least one of ``field.csv`` (full-field
displacements) and ``force.csv`` (load path and measured reaction). ``[loading] test`` selects
the experiment plug-in (:mod:`fabricsurf.experiments`), which validates its own keys; every
other key or table is checked against the contract, and an unknown one is rejected by name.
:func:`load_experiment` converts everything to mm and N and rejects bad input with one
:class:`DataError` naming the file, the row (line number, header = line 1) or key, and the
problem. :func:`write_experiment` writes a directory atomically (a temporary directory, then a
rename), so a reader never sees half-written data.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.errors import DataError
from fabricsurf.experiments import get_test
from fabricsurf.experiments.base import PluginSetup, number_option
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.contract.shear import read_shear, zero_shear
from fabricsurf.inverse.contract.tables import read_csv, read_toml
from fabricsurf.inverse.contract.writer import write_experiment

LENGTH_UNITS = {"mm": 1.0, "m": 1000.0}
FORCE_UNITS = {"N": 1.0, "mN": 1e-3, "kN": 1e3}
FIELD_COLUMNS = ("step", "X", "Y", "ux", "uy")
FORCE_COLUMNS = ("step", "displacement", "force")
CONTRACT_KEYS = {
    "": ("name", "units", "specimen", "loading", "data", "source", "material"),
    "units": ("length", "force"),
    "specimen": ("length", "width", "fibre_angles_deg"),
    "loading": ("test", "path"),
    "data": ("field", "force", "shear", "noise_std", "force_noise_std", "shear_noise_deg"),
}
"""Keys of the contract common to every test; plug-ins add their own (``keys``)."""
__all__ = ["DataError", "Experiment", "load_experiment", "write_experiment"]


def _get(t: dict, section: str, key: str):
    if key not in t.get(section, {}):
        raise DataError(f"experiment.toml: missing key [{section}] {key}")
    return t[section][key]


def _choice(value, label: str, allowed) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise DataError(f"experiment.toml: {label} = {value!r} is not one of {list(allowed)}")
    return value


def _check_keys(t: dict, plugin) -> None:
    """Reject tables and keys that neither the contract nor the plug-in knows."""
    allowed = {k: set(v) for k, v in CONTRACT_KEYS.items()}
    for table, keys in plugin.keys.items():
        allowed.setdefault(table, set()).update(keys)
        allowed[""].add(table)
    for key, value in t.items():
        if key not in allowed[""]:
            raise DataError(
                f"experiment.toml: unknown key or table '{key}' (known: "
                f"{', '.join(sorted(allowed['']))})"
            )
        if key == "source":
            bad = (
                [k for k, v in value.items() if not isinstance(v, str)]
                if isinstance(value, dict)
                else ["(not a table)"]
            )
            if bad:
                raise DataError(f"experiment.toml: [source] {bad[0]} must be free text")
            continue
        if isinstance(value, dict):
            extra = sorted(set(value) - allowed.get(key, set()))
            if extra:
                raise DataError(
                    f"experiment.toml: unknown key [{key}] {extra[0]} for test "
                    f"'{plugin.name}' (known in [{key}]: "
                    f"{', '.join(sorted(allowed.get(key, ()))) or 'none'})"
                )
        elif key != "name":
            raise DataError(f"experiment.toml: '{key}' must be a table [{key}]")


def _item(values: list, i: int, label: str) -> float:
    """``values[i]`` as a finite number; otherwise an error naming ``label[i]`` (a string
    such as '45' where a number belongs is the common case)."""
    v = values[i]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise DataError(
            f"experiment.toml: {label}[{i}] = {v!r} must be a finite number"
            + (" (written without quotes)" if isinstance(v, str) else "")
        )
    return float(v)


def _setup(t: dict, plugin, test: str, ls: float) -> PluginSetup:
    length = number_option(t, "specimen", "length", "experiment.toml") * ls
    width = number_option(t, "specimen", "width", "experiment.toml") * ls
    angles = _get(t, "specimen", "fibre_angles_deg")
    if not isinstance(angles, list) or len(angles) != 2:
        raise DataError(
            f"experiment.toml: [specimen] fibre_angles_deg = {angles!r} must be "
            "a list of two angles"
        )
    angles = tuple(_item(angles, i, "[specimen] fibre_angles_deg") for i in range(2))
    checks.fibre_angles(angles)
    setup = PluginSetup(test, length, width, angles, plugin.parse_options(t, ls, "experiment.toml"))
    plugin.check_specimen(setup, "experiment.toml")
    return setup


def _force_file(d: Path, gname: str, ls: float, fs: float) -> tuple:
    force = read_csv(d / gname, FORCE_COLUMNS)
    steps = checks.steps(force["step"], force["_line"], gname)
    checks.unique_steps(steps, force["_line"], gname)
    checks.forces(force["force"] * fs, force["_line"], gname)
    order = np.argsort(steps)
    return steps[order], force["displacement"][order] * ls, force["force"][order] * fs


def _path_from_toml(t: dict, scale: float) -> tuple[np.ndarray, np.ndarray]:
    path = t.get("loading", {}).get("path")
    if path is None:
        raise DataError(
            "experiment.toml: a field-only experiment needs its load path: "
            "[loading] path = [value per step, steps numbered from 1]"
        )
    if not isinstance(path, list) or not path:
        raise DataError(f"experiment.toml: [loading] path = {path!r} must be a non-empty list")
    vals = [_item(path, i, "[loading] path") for i in range(len(path))]
    return np.arange(1, len(vals) + 1), np.array(vals) * scale


def _files_here(t: dict, d: Path) -> dict:
    """A plug-in's option that names a file (a key ending in ``_file``, e.g. the punch's
    surface) is a path relative to the experiment's directory: made absolute here."""
    for table in t.values():
        if isinstance(table, dict):
            for k, v in table.items():
                if k.endswith("_file") and isinstance(v, str) and v.strip():
                    table[k] = str(d / v) if not Path(v).is_absolute() else v
    return t


def load_experiment(directory: str | Path) -> Experiment:
    """Read, validate and convert (to mm, N) the experiment in ``directory``."""
    d = Path(directory)
    if not d.is_dir():
        raise DataError(f"{d}: not a directory")
    t = _files_here(read_toml(d / "experiment.toml"), d)
    test = _get(t, "loading", "test")
    plugin = get_test(test)
    _check_keys(t, plugin)
    lu = _choice(_get(t, "units", "length"), "[units] length", LENGTH_UNITS)
    fu = _choice(_get(t, "units", "force"), "[units] force", FORCE_UNITS)
    ls, fs = LENGTH_UNITS[lu], FORCE_UNITS[fu]
    setup = _setup(t, plugin, plugin.name, ls)
    data = t.get("data", {})
    fname, gname, sname = data.get("field"), data.get("force"), data.get("shear")
    for key, v in (("field", fname), ("force", gname), ("shear", sname)):
        if v is not None and (not isinstance(v, str) or not v.strip()):
            raise DataError(
                f"experiment.toml: [data] {key} = {v!r} must be a file name in "
                f'quotes, e.g. {key} = "{key}.csv"'
            )
    if fname is None and gname is None and sname is None:
        raise DataError(
            'experiment.toml: [data] needs field = "...", force = "..." or '
            'shear = "..." (or several)'
        )
    if gname is not None and not plugin.has_reaction:
        raise DataError(
            f"experiment.toml: [data] force: the '{plugin.name}' test measures no "
            "reaction; give its load path as [loading] path"
        )
    pscale = ls if plugin.path_unit == "length" else 1.0
    if gname is not None:
        if "path" in t.get("loading", {}):
            raise DataError(
                "experiment.toml: [loading] path and [data] force both give the load path; keep one"
            )
        steps, path, force = _force_file(d, str(gname), pscale, fs)
    else:
        (steps, path), force = _path_from_toml(t, pscale), None
    plugin.check_path(
        steps, path, str(gname) if gname is not None else "experiment.toml: [loading] path"
    )
    noise = {
        k: (number_option(t, "data", k, "experiment.toml") * s if k in data else None)
        for k, s in (("noise_std", ls), ("force_noise_std", fs), ("shear_noise_deg", 1.0))
    }
    checks.noise_keys(noise, {"field": fname, "force": gname, "shear": sname})
    name = t.get("name", d.name)
    if not isinstance(name, str) or not name.strip():
        raise DataError(f"experiment.toml: name = {name!r} must be a non-empty string")
    exp = Experiment(
        name,
        setup,
        steps,
        path,
        force,
        noise_std=noise["noise_std"],
        force_noise_std=noise["force_noise_std"],
        shear_noise_deg=noise["shear_noise_deg"],
        source=dict(t.get("source", {})),
        directory=str(d.resolve()),
        files=tuple(str(d / f) for f in ("experiment.toml", fname, gname, sname) if f is not None),
    )
    if fname is not None:
        _read_field(exp, d / str(fname), ls, plugin.d)
    if sname is not None:
        read_shear(exp, d / str(sname), ls, plugin)
        zero_shear(exp, str(sname))
    checks.magnitudes(exp, lu)
    if force is not None:
        checks.tensile_forces(
            plugin,
            [int(k) for k in steps],
            force,
            str(gname),
            noise["force_noise_std"],
            label="numbered",
        )
    check_field_moves(exp, str(fname) if fname is not None else "")  # before: its remedy
    checks.zero_data(exp, fname and str(fname), gname and str(gname))
    return exp


STILL = 1e-12
"""A step's displacements are "zero" when none exceeds this fraction of the specimen size:
round-off of an exact 0, never a measurement (DIC noise alone is ~1e-3 mm)."""


def check_field_moves(exp: Experiment, name: str) -> None:
    """Refuse a field whose displacements are all zero at a step where the load path is not:
    the grip (or load) moved and nothing in the data did, the wrong columns (strains, a
    reference image exported for every step) or the wrong images; a fit would report it as a
    misfit no effect explains. ``name``: the field file's name, for the message."""
    if not exp.has_field:
        return
    size = max(exp.length, exp.width)
    still = [
        k
        for k, s in enumerate(exp.steps)
        if exp.path[k] != 0
        and len(rows := exp.step_rows(s))
        and np.abs(exp.u[rows]).max() <= STILL * size
    ]
    if not still:
        return
    label = get_test(exp.test).path_label
    steps = ", ".join(str(int(exp.steps[k])) for k in still[:8]) + (", …" if len(still) > 8 else "")
    path = ", ".join(f"{exp.path[k]:g}" for k in still[:8]) + (", …" if len(still) > 8 else "")
    every = len(still) == len(np.unique(exp.field_step))
    raise DataError(
        f"{name or 'the field'}: every displacement of step"
        f"{'s' * (len(still) > 1)} {steps}{' (all its steps)' * every} is 0 while "
        f"the {label} is {path}: nothing moved in the data though the load did; "
        "check the displacement columns (ux, uy: not strains or coordinates) and "
        "that each step's images are the loaded ones, not the reference image"
    )


def _read_field(exp: Experiment, path: Path, ls: float, d: int) -> None:
    f = read_csv(path, FIELD_COLUMNS, optional=("uz",))
    name = path.name
    if d == 3 and "uz" not in f:
        raise DataError(
            f"{name}: no column uz; the '{exp.test}' test is out of plane (its "
            "data are the deflection uz): give step,X,Y,ux,uy,uz"
        )
    f["step"] = checks.steps(f["step"], f["_line"], name)
    f["X"], f["Y"] = f["X"] * ls, f["Y"] * ls
    checks.field_rows(
        f,
        exp.steps,
        exp.length,
        exp.width,
        name,
        "the force file" if exp.has_force else "[loading] path",
    )
    comps = ["ux", "uy"] + (["uz"] if "uz" in f else [])
    u = np.column_stack([f[c] for c in comps]) * ls
    checks.field_displacements(u, f["_line"], max(exp.length, exp.width), name)
    exp.field_step = f["step"]
    exp.X = np.column_stack([f["X"], f["Y"]])
    exp.u = u
