"""Writing an experiment as a measurement directory (contract version 2), atomically."""

from __future__ import annotations

import csv
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from fabricsurf.errors import DataError
from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.checks import NOISE_DATA
from fabricsurf.inverse.contract.experiment import Experiment


def _toml_value(v) -> str:
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else repr(v)


def _plugin_tables(plugin, options: dict) -> dict[str, dict]:
    """The plug-in's keys of ``options`` by table. A key whose value the plug-in's parser
    refuses when written but gives when the key is absent (a default that the key itself may
    not take, e.g. "no self-weight" as an areal density of 0) is left out."""
    tables: dict[str, dict] = {}
    for table, keys in plugin.keys.items():
        for k in keys:
            if k in options:
                tables.setdefault(table, {})[k] = options[k]
    for table, k in [(t, k) for t, kv in tables.items() for k in kv]:
        if _parsed(plugin, tables) is not None:
            break
        rest = {t: {q: v for q, v in d.items() if (t, q) != (table, k)} for t, d in tables.items()}
        parsed = _parsed(plugin, rest)
        if parsed is not None and parsed.get(k) == tables[table][k]:
            tables = rest
    return {t: kv for t, kv in tables.items() if kv}


def _parsed(plugin, tables: dict) -> dict | None:
    """The plug-in's options from ``tables``, None if its parser refuses them."""
    try:
        return plugin.parse_options(tables, 1.0, "")
    except DataError:
        return None


def toml_text(exp: Experiment) -> str:
    """experiment.toml of ``exp`` (units mm and N; the plug-in's options in their tables)."""
    plugin = get_test(exp.test)
    tables: dict[str, dict] = {
        "units": {"length": "mm", "force": "N"},
        "specimen": {
            "length": exp.length,
            "width": exp.width,
            "fibre_angles_deg": [float(a) for a in exp.fibre_angles_deg],
        },
        "loading": {"test": exp.test},
        "data": {},
    }
    for table, kv in _plugin_tables(plugin, exp.setup.options).items():
        tables.setdefault(table, {}).update(kv)
    if not exp.has_force:
        tables["loading"]["path"] = [float(p) for p in exp.path]
    if exp.has_field:
        tables["data"]["field"] = "field.csv"
    if exp.has_force:
        tables["data"]["force"] = "force.csv"
    if exp.has_shear:
        tables["data"]["shear"] = "shear.csv"
    for key, kind in NOISE_DATA.items():  # the noise of the data written only
        if getattr(exp, key) is not None and kind in tables["data"]:
            tables["data"][key] = float(getattr(exp, key))
    if exp.source:
        tables["source"] = dict(exp.source)
    lines = [f"name = {json.dumps(exp.name)}"]
    for table, kv in tables.items():
        lines.append(f"[{table}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in kv.items()]
    return "\n".join(lines) + "\n"


def _table(path: Path, header: list[str], steps, *columns) -> None:
    """One CSV of the contract: the step, then ``columns`` (arrays, one row per step entry),
    each number as ``repr`` (the shortest text that reads back as the same float)."""
    rows = np.column_stack([np.asarray(c, float) for c in columns]).tolist()
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(
            [s, *map(repr, row)] for s, row in zip(np.asarray(steps).astype(int).tolist(), rows)
        )


def write_files(directory: str | Path, exp: Experiment) -> None:
    """The contract files of ``exp`` (experiment.toml and its CSVs, mm and N, every number at
    full precision, so a load gives back the very floats) into the existing ``directory``
    (a staging directory: no atomic replacement, :func:`write_experiment` does that); the one
    writer of the contract's files (the DIC import writes with it too). Call on one rank."""
    d = Path(directory)
    (d / "experiment.toml").write_text(toml_text(exp))
    if exp.has_force:
        _table(d / "force.csv", ["step", "displacement", "force"], exp.steps, exp.path, exp.force)
    if exp.has_field:
        comps = ["ux", "uy", "uz"][: exp.u.shape[1]]
        _table(d / "field.csv", ["step", "X", "Y", *comps], exp.field_step, exp.X, exp.u)
    if exp.has_shear:
        _table(
            d / "shear.csv", ["step", "X", "Y", "shear_deg"], exp.shear_step, exp.shear_X, exp.shear
        )


def write_experiment(directory: str | Path, exp: Experiment, overwrite: bool = False) -> Path:
    """Write ``exp`` (mm, N) as a measurement directory, atomically. Call on one rank only."""
    d = Path(directory)
    if d.exists() and not overwrite:
        raise FileExistsError(f"{d}: exists (pass overwrite=True to replace it)")
    d.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{d.name}.", dir=d.parent))
    try:
        write_files(tmp, exp)
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
