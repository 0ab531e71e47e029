"""One image's points, checked and moved to the specimen's frame (the importer's per-image work,
:mod:`~fabricsurf.inverse.dic.importer`): the header's unit tags against [units], the valid rows
(no hole, no lost-point flag), no duplicated point, every point on the specimen (or dropped,
``[frame] outside = "drop"``), displacements of a plausible size, and a field that spans the
specimen; each error names the file and line, and what to check.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.errors import DataError
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.dic.description.spec import ImportSpec
from fabricsurf.inverse.dic.layouts import UNITS
from fabricsurf.inverse.dic.reader import ExportFile

OUTLINE_TOL = 1e-6
"""Points this far outside the specimen (relative to its size) still count as on it."""


MAX_DISPLACEMENT = 10.0
"""Displacements beyond this many specimen sizes are a unit mix-up (the contract's limit,
checks.field_displacements, here with the export's file and line)."""


def check_units(f: ExportFile, unit: str) -> None:
    """The unit tags of the header (``u [mm]``) must agree with each other and [units]."""
    tagged = {
        r: UNITS[t.lower()]
        for r, t in f.units.items()
        if t is not None and t.lower() in UNITS and r not in ("px", "py")
    }
    if len(set(tagged.values())) > 1:
        pairs = ", ".join(f"{r} in {t}" for r, t in tagged.items())
        raise DataError(
            f"{f.path.name} line {f.header_line}: mixed units in the header "
            f"({pairs}); convert the export to one unit"
        )
    if tagged and next(iter(tagged.values())) != unit:
        r, t = next(iter(tagged.items()))
        raise DataError(
            f"{f.path.name} line {f.header_line}: the {r} column is in {t} but "
            f'[units] coordinates is "{unit}" (the layout\'s default or as given)'
        )


def valid_rows(f: ExportFile, spec: ImportSpec, d: int) -> np.ndarray:
    """Valid rows: finite coordinates and displacements (w only where used), no lost-point
    flag, and, for layouts that write zeros for lost points, not all-zero (unless every row
    is: an image of zero displacements)."""
    ok = np.ones(f.n, dtype=bool)
    used = ("x", "y", "u", "v") + (("w",) if d == 3 else ())
    for role in used:
        if role in f.data:
            ok &= np.isfinite(f.data[role])
    for role, value in spec.layout.lost_flags():
        if role in f.data:
            ok &= f.data[role] != value
    if spec.layout.zero_lost:
        zero = np.ones(f.n, dtype=bool)
        for role in ("u", "v", "w"):
            if role in f.data:
                zero &= f.data[role] == 0.0
        if not zero[ok].all():
            ok &= ~zero
    return ok


def _duplicates(f: ExportFile, rows: np.ndarray) -> None:
    x, y = f.data["x"][rows], f.data["y"][rows]
    order = np.lexsort((y, x))
    same = np.flatnonzero((np.diff(x[order]) == 0) & (np.diff(y[order]) == 0))
    if len(same):
        a, b = sorted((rows[order[same[0]]], rows[order[same[0] + 1]]))
        raise DataError(
            f"{f.path.name} line {f.line_of(b)}: duplicated point (x, y) = "
            f"({f.data['x'][b]:g}, {f.data['y'][b]:g}), also on line {f.line_of(a)}"
        )


def _outline(f: ExportFile, rows: np.ndarray, X: np.ndarray, spec: ImportSpec) -> np.ndarray:
    """Mask of the points on the specimen; a point off it is an error (outside = "error")."""
    L, W = spec.setup.length, spec.setup.width
    tol = OUTLINE_TOL * max(L, W)
    on = (X[:, 0] >= -tol) & (X[:, 0] <= L + tol) & (X[:, 1] >= -tol) & (X[:, 1] <= W + tol)
    if spec.outside == "error" and not on.all():
        i = int(np.flatnonzero(~on)[0])
        r = rows[i]
        raise DataError(
            f"{f.path.name} line {f.line_of(r)}: point (x, y) = ({f.data['x'][r]:g},"
            f" {f.data['y'][r]:g}) {spec.unit} lies at (X, Y) = ({X[i, 0]:.4g}, "
            f"{X[i, 1]:.4g}) mm, outside the specimen [0, {L:g}] x [0, {W:g}] mm "
            "(check [frame] origin, grip, angle_deg and [units]; or set [frame] "
            'outside = "drop" to drop such points, e.g. on the grips)'
        )
    return on


def _magnitudes(f: ExportFile, rows: np.ndarray, u: np.ndarray, spec: ImportSpec) -> None:
    """Displacements beyond ten times the specimen are a unit or scale mix-up."""
    size = max(spec.setup.length, spec.setup.width)
    big = np.flatnonzero(np.abs(u).max(axis=1) > MAX_DISPLACEMENT * size)
    if len(big):
        i = big[0]
        raise DataError(
            f"{f.path.name} line {f.line_of(rows[i])}: displacement of "
            f"{np.abs(u[i]).max():.3g} mm, more than "
            f"{MAX_DISPLACEMENT:g} times the specimen size ({size:g} "
            "mm): check [units] (coordinates, mm_per_pixel) and the columns"
        )


def points_of_image(
    f: ExportFile, spec: ImportSpec, d: int, first: bool, ok: np.ndarray
) -> tuple[np.ndarray, ...]:
    """(X, u, counts) of one image's valid points (``ok``) in the specimen's frame."""
    rows = np.flatnonzero(ok)
    _duplicates(f, rows)
    data = {r: a[rows] for r, a in f.data.items()}
    X = np.column_stack(spec.frame.points(data["x"], data["y"]))
    if first:
        spec.frame.check_tilt(X[:, 0], X[:, 1], f.path.name)
    comps = spec.frame.vectors(data["u"], data["v"], data.get("w") if d == 3 else None)
    if d == 3 and len(comps) < 3:
        raise DataError(
            f"{f.path.name}: no out-of-plane displacement column (the "
            f"{spec.layout.name} layout's w); the '{spec.setup.test}' test needs uz"
        )
    on = _outline(f, rows, X, spec)
    u = np.column_stack(comps)[on]
    _magnitudes(f, rows[on], u, spec)
    counts = {
        "rows": f.n,
        "holes": int(f.n - len(rows)),
        "outside_dropped": int((~on).sum()),
        "points": int(on.sum()),
        "max_abs_u_mm": float(np.abs(u).max()) if len(u) else 0.0,
    }
    return X[on], u, counts


def check_not_empty(name: str, counts: dict, spec: ImportSpec) -> None:
    """An image with no valid point on the specimen, said with why (holes or outline)."""
    if counts["points"]:
        return
    if counts["holes"] == counts["rows"]:
        raise DataError(
            f"{name}: every one of its {counts['rows']} rows is a hole (NaN, empty "
            f"or the {spec.layout.name} layout's invalid marker): the correlation "
            "lost this image; leave it out of [steps] images"
        )
    raise DataError(
        f"{name}: no point left on the specimen ({counts['holes']} holes, "
        f"{counts['outside_dropped']} points outside it dropped by [frame] outside "
        '= "drop"): check [frame] origin, grip, angle_deg and [units]'
    )


def check_extent(name: str, X: np.ndarray, spec: ImportSpec) -> None:
    """Points gathered in a patch far smaller than the specimen: a scale off by orders of
    magnitude (mm_per_pixel, [units]), refused here rather than by the loader later."""
    L, W = spec.setup.length, spec.setup.width
    ex, ey = np.ptp(X[:, 0]), np.ptp(X[:, 1])
    if (
        len(np.unique(X, axis=0)) >= 4
        and ex < checks.MIN_FIELD_EXTENT * L
        and ey < checks.MIN_FIELD_EXTENT * W
    ):
        raise DataError(
            f"{name}: the points span {ex:.3g} x {ey:.3g} mm of the {L:g} x {W:g} mm "
            f"specimen at {spec.frame.scale:g} mm per {spec.unit}: is the scale "
            "([units] mm_per_pixel, or the coordinates' unit) right?"
        )
