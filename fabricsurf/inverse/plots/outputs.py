"""Writing comparisons: misfit JSON, per-point CSV and figures for each experiment."""

from __future__ import annotations

import hashlib
import re
import unicodedata
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import on_rank0, write_json
from fabricsurf.inverse.fitting.result import strip_rows
from fabricsurf.inverse.plots import figures
from fabricsurf.inverse.plots import formed_shear as shear

SLUG_CHARS = 60


def slug(name: str) -> str:
    """A file-name-safe (ASCII) form of an experiment name. Characters outside ASCII are
    dropped after their accents (NFKD), and a short hash of the whole name is appended then,
    or when the name is longer than SLUG_CHARS: names in other scripts (two Chinese names
    would otherwise both become "experiment") stay distinct, and prefixes stay short."""
    ascii_ = unicodedata.normalize("NFKD", name).encode("ascii", "ignore").decode()
    s = re.sub(r"[^A-Za-z0-9_.-]+", "_", ascii_).strip("_")
    if not name.isascii() or len(s) > SLUG_CHARS:
        tag = hashlib.sha256(name.encode()).hexdigest()[:8]
        s = f"{s[:SLUG_CHARS]}_{tag}" if s else f"experiment_{tag}"
    return s or "experiment"


CSV_BLOCK = 1 << 16
"""Rows formatted per block of the per-point CSV (bounded memory; %-formatting a block at once
is about twice as fast as a csv.writer row by row)."""


def _per_point(path: Path, exp, pred, err) -> None:
    """One row per field point: step, coordinates, measured and model displacements and their
    distance, in mm whatever the input's [units] (the column names say so); 10 significant
    digits, far below any measurement's resolution."""
    c = pred.u.shape[1]
    comps = ["ux", "uy", "uz"][:c]
    cols = np.column_stack([exp.X[:, :2], exp.u[:, :c], pred.u, err])
    fmt = "%d" + ",%.10g" * cols.shape[1] + "\n"
    with open(path, "w", newline="") as fh:
        fh.write(
            ",".join(
                [
                    "step",
                    "X_mm",
                    "Y_mm",
                    *(f"{k}_meas_mm" for k in comps),
                    *(f"{k}_model_mm" for k in comps),
                    "error_mm",
                ]
            )
            + "\n"
        )
        for a in range(0, len(cols), CSV_BLOCK):
            block = np.column_stack([exp.field_step[a : a + CSV_BLOCK], cols[a : a + CSV_BLOCK]])
            fh.write((fmt * len(block)) % tuple(block.ravel()))


def _figures(out: Path, exp, preds: list, misfits: list, steps, stem: str) -> None:
    pred = preds[-1][1]
    if exp.has_field:
        _per_point(out / f"{stem}per_point.csv", exp, pred, misfits[-1][1]["row_error"])
        figures.error_map(
            exp, preds, steps or figures.default_steps(exp), out / f"{stem}error_map.png"
        )
    if exp.has_force:
        figures.force_curves(exp, preds, out / f"{stem}force.png")
    if exp.has_shear:
        shear.per_point_csv(out / f"{stem}shear_per_point.csv", exp, pred)
        shear.shear_figure(exp, preds, out / f"{stem}shear.png")
    figures.error_vs_step(exp, misfits, out / f"{stem}error_vs_step.png")


def write_comparison(
    out: Path,
    exps: list,
    preds: list[tuple[str, list]],
    misfits: list[tuple[str, dict]],
    steps: list[int] | None = None,
    stem: str = "",
    extra: dict | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> None:
    """``preds``/``misfits``: (label, per-experiment list / joint misfit dict) per model; the
    last one is the model reported in ``{stem}misfit.json``. One experiment: files
    ``{stem}error_map.png`` etc.; several: prefixed by each experiment's name."""
    label, m = misfits[-1]
    write_json(comm, out / f"{stem}misfit.json", strip_rows(m) | {"model": label} | (extra or {}))
    for i, exp in enumerate(exps):
        pre = stem + ("" if len(exps) == 1 else f"{slug(exp.name)}_")
        per_m = [(lab, mm["experiments"][i]) for lab, mm in misfits]
        per_p = [(lab, pp[i]) for lab, pp in preds]
        on_rank0(comm, _figures, out, exp, per_p, per_m, steps, pre)


def field_band_csv(path: Path, exp, half: np.ndarray) -> None:
    comps = ["ux", "uy", "uz"][: half.shape[1]]
    rows = np.column_stack([exp.field_step, exp.X[:, :2], half])
    np.savetxt(
        path,
        rows,
        delimiter=",",
        fmt="%.6g",
        comments="",
        header=",".join(["step", "X_mm", "Y_mm", *(f"{c}_half_width_mm" for c in comps)]),
    )
