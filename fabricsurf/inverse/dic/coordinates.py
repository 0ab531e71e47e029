"""Reference or deformed coordinates: converting the second to the first, and checking, image
by image against the first image read, that the coordinates behave as declared.

Some programs write each point's position in the reference image (DICe, VIC, the ARAMIS
nodemap's ``x_undef``), others its position in the image itself (MatchID's ``x, y, z`` and
``coor.X``, DaVis): there reference = deformed − displacement, in the export's own frame and
unit, before the frame transform (z − w when both are given). Declared wrongly, every point is
misplaced by its displacement.

The evidence: points of two images are matched (by their integer pixel position when the
layout has one, by row when the files have as many rows), and for the points whose
displacement changed clearly between the two images, x₂ − x₁ is compared with u₂ − u₁ (deformed
coordinates move with their points) and with 0 (reference coordinates stay). Memory: the first
image's valid coordinates and displacements, O(N), kept while the others are compared.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabricsurf.errors import DataError

REL_TOL = 1e-4
"""Agreement of x₂ − x₁ with u₂ − u₁ (or 0), relative to the values compared: exports print
5 (DICe: 5.5500E+02) to 10 significant digits, so 1e-4 of the values covers their printing."""
MIN_MOVED = 20
"""Points whose displacement changed by more than ten tolerances, needed for a verdict."""
DECISIVE = 0.9
"""Fraction of those points that must follow one reading for the import to be refused."""


def to_reference(data: dict[str, np.ndarray]) -> None:
    """Deformed → reference coordinates, in place: x − u, y − v, and z − w when both exist."""
    data["x"] = data["x"] - data["u"]
    data["y"] = data["y"] - data["v"]
    if "z" in data and "w" in data:
        data["z"] = data["z"] - data["w"]


@dataclass
class Anchor:
    """The first image read: its valid points' raw columns (export frame and unit)."""

    image: int
    name: str
    n: int
    cols: dict[str, np.ndarray]
    rows: np.ndarray


def anchor(image: int, name: str, data: dict[str, np.ndarray], ok: np.ndarray) -> Anchor:
    """Keep what the later images are compared with (valid rows only)."""
    rows = np.flatnonzero(ok)
    keep = {r: data[r][rows].copy() for r in ("x", "y", "u", "v", "px", "py") if r in data}
    return Anchor(image, name, len(ok), keep, rows)


def _pixel_key(px: np.ndarray, py: np.ndarray) -> np.ndarray:
    ix, iy = np.rint(px).astype(np.int64), np.rint(py).astype(np.int64)
    return ix * (1 << 31) + iy


def _match(
    a: Anchor, data: dict[str, np.ndarray], ok: np.ndarray
) -> tuple[np.ndarray, np.ndarray, str] | None:
    """(indices into the anchor's kept rows, rows of this image, how) or None."""
    rows = np.flatnonzero(ok)
    if "px" in a.cols and "py" in data and "px" in data:
        ka = _pixel_key(a.cols["px"], a.cols["py"])
        kb = _pixel_key(data["px"][rows], data["py"][rows])
        _, ia, ib = np.intersect1d(ka, kb, assume_unique=False, return_indices=True)
        return ia, rows[ib], "their integer pixel position"
    if len(ok) == a.n:
        _, ia, ib = np.intersect1d(a.rows, rows, assume_unique=True, return_indices=True)
        return ia, rows[ib], "row (both files have the same rows)"
    return None


def compare(
    a: Anchor,
    image: int,
    name: str,
    data: dict[str, np.ndarray],
    ok: np.ndarray,
    declared: str,
    key: str,
) -> dict:
    """The evidence of this image against the anchor; a DataError when it contradicts the
    ``declared`` reading ("reference" or "deformed"; ``key`` is the key that sets it)."""
    m = _match(a, data, ok)
    if m is None:
        return {
            "image": image,
            "checked": False,
            "why": "row counts differ and the layout has no pixel position columns",
        }
    ia, rb, how = m
    xa, ya, ua, va = (a.cols[r][ia] for r in ("x", "y", "u", "v"))
    xb, yb, ub, vb = (data[r][rb] for r in ("x", "y", "u", "v"))
    floor = 1e-12 * (float(np.abs(xa).max(initial=0.0)) + 1.0)
    tx = REL_TOL * (np.abs(xa) + np.abs(xb) + np.abs(ua) + np.abs(ub)) + floor
    ty = REL_TOL * (np.abs(ya) + np.abs(yb) + np.abs(va) + np.abs(vb)) + floor
    dx, dy, du, dv = xb - xa, yb - ya, ub - ua, vb - va
    moved = (np.abs(du) > 10 * tx) | (np.abs(dv) > 10 * ty)
    n = int(moved.sum())
    out = {
        "image": image,
        "against_image": a.image,
        "matched": len(ia),
        "matched_by": how,
        "moved": n,
    }
    if n < MIN_MOVED:
        return out | {"checked": False, "why": f"fewer than {MIN_MOVED} points moved"}
    follows = float(np.mean((np.abs(dx - du) <= tx)[moved] & (np.abs(dy - dv) <= ty)[moved]))
    stays = float(np.mean((np.abs(dx) <= tx)[moved] & (np.abs(dy) <= ty)[moved]))
    out |= {"checked": True, "move_with_displacement": follows, "stay": stays}
    if declared == "reference" and follows >= DECISIVE:
        raise DataError(
            f"{name}: x of image {image} − x of image {a.image} ({a.name}) equals "
            f"u of image {image} − u of image {a.image} (and y, v alike) to "
            f"{REL_TOL:g} of the values on {follows:.0%} of the {n} points that "
            f"moved, matched by {how}: these are deformed coordinates (each "
            f"point's position in its own image), read as reference ones; set "
            f'{key} = "deformed"'
        )
    if declared == "deformed" and stays >= DECISIVE:
        raise DataError(
            f"{name}: x of image {image} equals x of image {a.image} ({a.name}) "
            f"(and y alike) to {REL_TOL:g} of the values on {stays:.0%} of the {n} "
            f"points whose displacement changed, matched by {how}: these are "
            f"reference coordinates, read as deformed ones; set {key} = "
            '"reference"'
        )
    return out
