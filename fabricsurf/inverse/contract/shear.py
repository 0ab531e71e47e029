"""Measured shear angles at points of a formed part (``shear.csv``, docs/contracts.md): read and
checked like the field data, each bad row named with its file, line and value."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.errors import DataError
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.contract.tables import read_csv

SHEAR_COLUMNS = ("step", "X", "Y", "shear_deg")
MAX_SHEAR_DEG = 90.0
"""|γ| < 90°: at 90° the two fibre families would be parallel."""


def read_shear(exp, path: Path, ls: float, plugin) -> None:
    """Fill ``exp.shear_step``, ``shear_X`` (mm, the data's frame) and ``shear`` (deg) from
    ``path``; the test must take shear data (``plugin.takes_shear``)."""
    name = path.name
    if not plugin.takes_shear:
        raise DataError(
            f"experiment.toml: [data] shear = \"{name}\": the '{plugin.name}' test "
            "takes no measured shear angles (docs/contracts.md: the hemisphere "
            "does)"
        )
    f = read_csv(path, SHEAR_COLUMNS)
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
    _inside_circle(exp, f, name)
    big = np.flatnonzero(np.abs(f["shear_deg"]) >= MAX_SHEAR_DEG)
    if len(big):
        i = big[0]
        raise DataError(
            f"{name} line {f['_line'][i]}: shear_deg = {f['shear_deg'][i]:g} is "
            f"not a shear angle (|γ| < {MAX_SHEAR_DEG:g}°; the column is in "
            "degrees)"
        )
    exp.shear_step = f["step"]
    exp.shear_X = np.column_stack([f["X"], f["Y"]])
    exp.shear = f["shear_deg"].astype(float)


def _inside_circle(exp, f: dict, name: str) -> None:
    """On a circular blank the points must lie in the circle, not only in its square."""
    if exp.setup.options.get("blank", "square") != "circle":
        return
    r = 0.5 * exp.length
    beyond = np.hypot(f["X"] - r, f["Y"] - 0.5 * exp.width) - r
    out = np.flatnonzero(beyond > 1e-9 * r)
    if len(out):
        i = out[0]
        raise DataError(
            f"{name} line {f['_line'][i]}: point (X, Y) = ({f['X'][i]:g}, "
            f"{f['Y'][i]:g}) mm lies {beyond[i]:.3g} mm outside the circular blank "
            f"(diameter {exp.length:g} mm, centre ({r:g}, {0.5 * exp.width:g}) mm)"
        )


def zero_shear(exp, name: str | None) -> None:
    """All measured shear angles 0 without ``shear_noise_deg``: no misfit scale."""
    if exp.has_shear and exp.shear_noise_deg is None and not np.any(exp.shear):
        raise DataError(
            f"{name}: every shear angle is 0 and [data] shear_noise_deg is not "
            "given, so the misfit has no shear scale (the default is 1 % of the "
            "largest |shear_deg|); give shear_noise_deg (deg)"
        )
