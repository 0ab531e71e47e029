"""Validation and plausibility checks of measurement data (mm, N), each with a message naming
the file, line or key and what to check (unit mix-ups are the common cause of absurd values)."""

from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from fabricsurf.errors import DataError
from fabricsurf.log import warn

logger = logging.getLogger(__name__)

MAX_SPECIMEN_MM = 5000.0
MIN_SPECIMEN_MM = 0.5
MAX_FORCE_N = 1e7
MIN_FIELD_EXTENT = 0.02
MIN_FIBRE_ANGLE_DEG = 5.0
"""Least angle between the two fibre families (as lines): nearly parallel ones make the
membrane nearly singular across them, so a fit could trade one family against the other."""


def fibre_angles(angles: tuple[float, float]) -> None:
    """The two fibre families must cross at MIN_FIBRE_ANGLE_DEG or more (as lines: mod 180°)."""
    apart = abs(angles[0] - angles[1]) % 180.0
    apart = min(apart, 180.0 - apart)
    if apart < MIN_FIBRE_ANGLE_DEG:
        raise DataError(
            f"experiment.toml: [specimen] fibre_angles_deg = {list(angles)}: the "
            f"two fibre families are {apart:.3g}° apart, nearly parallel; they "
            f"must cross at {MIN_FIBRE_ANGLE_DEG:g}° or more"
        )


NOISE_DATA = {"noise_std": "field", "force_noise_std": "force", "shear_noise_deg": "shear"}
"""Each [data] noise key and the data file whose misfit it scales."""


def noise_keys(noise: dict, files: dict) -> None:
    """A shear-angle noise of 90° or more is no measurement (angles lie within ±90°); a noise
    level given for data the directory does not hold is ignored, and said so (rank 0)."""
    s = noise.get("shear_noise_deg")
    if s is not None and s >= 90.0:
        raise DataError(
            f"experiment.toml: [data] shear_noise_deg = {s:g} must be below 90 "
            "(degrees; the measured shear angles themselves lie within ±90°)"
        )
    for key, kind in NOISE_DATA.items():
        if noise.get(key) is not None and files.get(kind) is None:
            warn(
                logger,
                MPI.COMM_WORLD,
                f"experiment.toml: [data] {key} is given but "
                f"[data] {kind} is not: the noise level is not used",
            )


def steps(values: np.ndarray, lines: np.ndarray, name: str) -> np.ndarray:
    """Step numbers must be integers ≥ 1."""
    bad = np.flatnonzero((values != np.round(values)) | (values < 1))
    if len(bad):
        raise DataError(
            f"{name} line {lines[bad[0]]}: step {values[bad[0]]!r} is not an integer ≥ 1"
        )
    return values.astype(np.int64)


def _first_duplicate(keys: np.ndarray) -> tuple[int, int] | None:
    """(first row, repeat) of the earliest row of ``keys`` (n × k) that repeats an earlier
    one, None if the rows are distinct: a stable sort puts equal rows next to each other in
    their order in the file (O(n log n), no Python loop over the rows)."""
    if len(keys) < 2:
        return None
    order = np.lexsort(keys.T[::-1])
    ks = keys[order]
    same = np.all(ks[1:] == ks[:-1], axis=1)
    if not same.any():
        return None
    group = np.concatenate([[0], np.cumsum(~same)])
    first = order[np.concatenate([[0], np.flatnonzero(~same) + 1])]
    j = np.flatnonzero(same) + 1
    k = np.argmin(order[j])
    return int(first[group[j[k]]]), int(order[j[k]])


def unique_steps(st: np.ndarray, lines: np.ndarray, name: str) -> None:
    dup = _first_duplicate(st[:, None])
    if dup:
        raise DataError(
            f"{name} line {lines[dup[1]]}: duplicate step {st[dup[1]]} (also on "
            f"line {lines[dup[0]]})"
        )


def field_rows(
    f: dict, known_steps: np.ndarray, length: float, width: float, name: str, steps_source: str
) -> None:
    """Points inside the specimen, no duplicate rows, steps known to the load path."""
    tol = 1e-9 * max(length, width)
    X, Y, lines = f["X"], f["Y"], f["_line"]
    out = np.flatnonzero((X < -tol) | (X > length + tol) | (Y < -tol) | (Y > width + tol))
    if len(out):
        i = out[0]
        raise DataError(
            f"{name} line {lines[i]}: point (X, Y) = ({X[i]:g}, {Y[i]:g}) mm is "
            f"outside the specimen [0, {length:g}] x [0, {width:g}] mm (check the "
            "origin and [units] length)"
        )
    dup = _first_duplicate(np.column_stack([f["step"], X, Y]))
    if dup:
        raise DataError(
            f"{name} line {lines[dup[1]]}: duplicate row (same step, X, Y as line {lines[dup[0]]})"
        )
    unknown = np.flatnonzero(~np.isin(f["step"], known_steps))
    if len(unknown):
        i = unknown[0]
        raise DataError(
            f"{name} line {lines[i]}: step {int(f['step'][i])} does not appear in {steps_source}"
        )
    ex, ey = np.ptp(X), np.ptp(Y)
    if len(np.unique(np.column_stack([X, Y]), axis=0)) >= 4 and (
        ex < MIN_FIELD_EXTENT * length and ey < MIN_FIELD_EXTENT * width
    ):
        raise DataError(
            f"{name}: all points lie in a {ex:.3g} x {ey:.3g} mm patch of the "
            f"{length:g} x {width:g} mm specimen: are the field coordinates in "
            "another unit than [units] length?"
        )


def magnitudes(exp, length_unit: str) -> None:
    """Absurd magnitudes (unit mix-ups) rejected with what was found."""
    size = max(exp.length, exp.width)
    if size > MAX_SPECIMEN_MM or min(exp.length, exp.width) < MIN_SPECIMEN_MM:
        raise DataError(
            f"experiment.toml: [specimen] {exp.length:g} x {exp.width:g} mm is not "
            f'a plausible specimen (from [units] length = "{length_unit}"): are '
            "the sizes in another unit?"
        )
    where = (
        "the force file's displacement column"
        if exp.has_force
        else "experiment.toml: [loading] path"
    )
    if np.abs(exp.path).max() > 10 * size:
        k = int(np.argmax(np.abs(exp.path)))
        raise DataError(
            f"load path ({where}): step {exp.steps[k]} has the value "
            f"{exp.path[k]:.3g}, more than ten times the specimen size "
            f"({size:g} mm): check [units] length"
        )
    if exp.noise_std is not None and exp.noise_std > size:
        raise DataError(
            f"experiment.toml: [data] noise_std = {exp.noise_std:.3g} mm exceeds "
            f"the specimen size ({size:g} mm): check [units] length"
        )
    if exp.force_noise_std is not None and exp.force_noise_std > MAX_FORCE_N:
        raise DataError(
            f"experiment.toml: [data] force_noise_std = "
            f"{exp.force_noise_std:.3g} N is not plausible (check [units] force)"
        )


def zero_data(exp, field_name: str | None, force_name: str | None) -> None:
    """A measured curve (or field) that is all zero, without its noise level, has no misfit
    scale: the default, 1 % of the largest measured value, would be 0."""
    if exp.has_force and exp.force_noise_std is None and not np.any(exp.force):
        raise DataError(
            f"{force_name}: every force is 0 and [data] force_noise_std is not "
            "given, so the misfit has no force scale (the default is 1 % of the "
            "largest |force|); check the force column or give force_noise_std (N)"
        )
    if exp.has_field and exp.noise_std is None and not np.any(exp.u):
        raise DataError(
            f"{field_name}: every displacement is 0 and [data] noise_std is not "
            "given, so the misfit has no displacement scale (the default is 1 % "
            "of the largest displacement); check the columns or give noise_std "
            "(length units)"
        )


def field_displacements(u: np.ndarray, lines: np.ndarray, size: float, name: str) -> None:
    """Displacements larger than ten times the specimen are a unit or column mix-up."""
    big = np.flatnonzero(np.abs(u).max(axis=1) > 10 * size)
    if len(big):
        raise DataError(
            f"{name} line {lines[big[0]]}: displacement of "
            f"{np.abs(u[big[0]]).max():.3g} mm, more than ten times the specimen "
            f"size ({size:g} mm): check [units] length and the columns"
        )


def forces(f: np.ndarray, lines: np.ndarray, name: str) -> None:
    """Forces beyond any fabric test machine are a unit mix-up."""
    big = np.flatnonzero(np.abs(f) > MAX_FORCE_N)
    if len(big):
        raise DataError(
            f"{name} line {lines[big[0]]}: force {f[big[0]]:.3g} N is not plausible "
            "for a fabric test (check [units] force)"
        )


def unloading_warning(exp, model) -> str | None:
    """A warning when ``model`` holds a term valid for monotonic loading only (the elastic
    stand-in of a dissipative effect, ``Term.monotonic_only``) and the load path of ``exp``
    turns back: it names the experiment, the term and the first step that unloads."""
    terms = [t.name for t in model if getattr(t, "monotonic_only", False)]
    dp = np.diff(np.asarray(exp.path, float))
    moving = dp[dp != 0.0]
    if not terms or len(moving) < 2:
        return None
    back = np.flatnonzero(np.sign(dp) == -np.sign(moving[0]))
    if not len(back):
        return None
    k = int(back[0]) + 1
    return (
        f"{exp.name}: the load path turns back at step {int(exp.steps[k])} (from "
        f"{exp.path[k - 1]:g} to {exp.path[k]:g}); {', '.join(terms)} is an elastic "
        "equivalent for monotonic loading and does not describe unloading"
    )


def tensile_forces(
    plugin: type,
    images: list,
    force: list[float] | np.ndarray,
    where: str,
    force_noise_std: float | None = None,
    label: str = "step",
) -> None:
    """A test that pulls the specimen (a load path of displacements ≥ 0, ``path_unit`` "length"
    with a reaction: the bias-extension test) measures a tensile reaction, positive by the
    contract's sign convention: a negative force beyond the force noise (3 σ given, else 3 % of
    the largest |force|, three times the contract's default σ) is a reversed sign convention
    or a load cell read in compression. ``images``: a label per step (the image numbers, or the
    step numbers of a force file)."""
    if getattr(plugin, "path_unit", None) != "length" or not plugin.has_reaction:
        return
    f = np.asarray(force, float)
    if not len(f):
        return
    tol = 3.0 * (force_noise_std if force_noise_std is not None else 0.01 * float(np.abs(f).max()))
    bad = np.flatnonzero(f < -tol)
    if len(bad):
        k = int(bad[0])
        raise DataError(
            f"{where}: step {k + 1} ({label} {images[k]}): force {f[k]:.4g} N is "
            f"negative ({len(bad)} of {len(f)} steps are); the '{plugin.name}' test "
            "pulls the specimen and its reaction is tensile, positive by the "
            "contract's sign convention: flip the sign of the force column (the "
            "load cell's compression-positive convention) or check the channel"
        )
