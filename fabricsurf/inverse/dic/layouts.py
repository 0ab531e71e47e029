"""Column layouts of DIC point-cloud exports: which header names hold the reference
coordinates, the displacements and the validity flag, and in which unit (docs/dic.md says where
each layout was read from and how it was checked).

A header cell may carry its unit, ``u [mm]`` or ``x (pixel)``: the name is what precedes the
bracket; the unit is checked against the declared one (:func:`split_unit`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from fabricsurf.errors import DataError


@dataclass(frozen=True)
class Layout:
    """Header names of one export layout. ``x``, ``y``, ``u``, ``v`` are required; ``z``, ``w``
    are used when the header has them. ``valid``/``invalid``: a column whose value ``invalid``
    marks a lost point (VIC and DICe write sigma = -1). ``unit``: the coordinates' natural unit
    ("mm" or "pixel"); ``y_down``: image axes (y positive down)."""

    name: str
    x: str
    y: str
    u: str
    v: str
    z: str | None = None
    w: str | None = None
    valid: str | None = None
    invalid: float | None = None
    unit: str = "mm"
    y_down: bool = False
    source: str = ""

    def columns(self) -> dict[str, str]:
        """{role: header name} of the required and optional columns."""
        roles = {"x": self.x, "y": self.y, "u": self.u, "v": self.v, "z": self.z, "w": self.w,
                 "valid": self.valid}
        return {k: v for k, v in roles.items() if v is not None}


LAYOUTS = {
    "dice": Layout("dice", "COORDINATE_X", "COORDINATE_Y", "DISPLACEMENT_X", "DISPLACEMENT_Y",
                   valid="SIGMA", invalid=-1.0, unit="pixel", y_down=True,
                   source="DICe solution files (DICe_solution_N.txt)"),
    "vic2d": Layout("vic2d", "x", "y", "u", "v", valid="sigma", invalid=-1.0, unit="pixel",
                    y_down=True, source="VIC-2D CSV export, image columns"),
    "vic2d_metric": Layout("vic2d_metric", "X", "Y", "U", "V", valid="sigma", invalid=-1.0,
                           unit="mm", source="VIC-2D CSV export, calibrated columns"),
    "vic3d": Layout("vic3d", "X", "Y", "U", "V", z="Z", w="W", valid="sigma", invalid=-1.0,
                    unit="mm", source="VIC-3D CSV export"),
    "aramis_nodemap": Layout("aramis_nodemap", "x_undef", "y_undef", "u", "v", z="z_undef",
                             w="w", unit="mm",
                             source="ZEISS GOM ARAMIS nodemap (aramis-data-exporter)"),
}
"""The layouts read by name; any other through ``layout = "columns"`` and a [columns] table."""

UNITS = {"mm": "mm", "millimeter": "mm", "millimetre": "mm", "m": "m", "pixel": "pixel",
         "pixels": "pixel", "px": "pixel", "pix": "pixel"}
"""Unit tags of header cells, normalised; other tags (%, 1, ...) are not length units."""
_TAG = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")


def split_unit(cell: str) -> tuple[str, str | None]:
    """(name, unit tag or None) of a header cell: ``"u [mm]"`` → ("u", "mm")."""
    cell = cell.strip().strip('"').strip("'").strip()
    m = _TAG.match(cell)
    if not m:
        return cell, None
    return m.group(1).strip(), m.group(2).strip()


def custom_layout(table: dict, where: str) -> Layout:
    """A layout from the [columns] table: x, y, u, v (required), z, w, valid, invalid
    (optional), unit ("mm" or "pixel"), y_down."""
    known = {"x", "y", "u", "v", "z", "w", "valid", "invalid", "unit", "y_down"}
    extra = sorted(set(table) - known)
    if extra:
        raise DataError(f"{where}: unknown key [columns] {extra[0]} (known: "
                        f"{', '.join(sorted(known))})")
    names = {}
    for key in ("x", "y", "u", "v", "z", "w", "valid"):
        if key not in table:
            if key in "xyuv":
                raise DataError(f"{where}: layout \"columns\" needs [columns] {key} = \"header "
                                "name\" (x, y, u, v required; z, w, valid optional)")
            continue
        if not isinstance(table[key], str) or not table[key].strip():
            raise DataError(f"{where}: [columns] {key} = {table[key]!r} must be a header name")
        names[key] = table[key].strip()
    invalid = table.get("invalid")
    if invalid is not None and (isinstance(invalid, bool) or not isinstance(invalid,
                                                                            (int, float))):
        raise DataError(f"{where}: [columns] invalid = {invalid!r} must be a number")
    if (invalid is None) != ("valid" not in names):
        raise DataError(f"{where}: [columns] valid and invalid go together (the column and "
                        "the value in it that marks a lost point)")
    unit = table.get("unit", "mm")
    if unit not in ("mm", "pixel"):
        raise DataError(f"{where}: [columns] unit = {unit!r} is not one of ['mm', 'pixel']")
    y_down = table.get("y_down", unit == "pixel")
    if not isinstance(y_down, bool):
        raise DataError(f"{where}: [columns] y_down = {y_down!r} must be true or false")
    return Layout("columns", invalid=None if invalid is None else float(invalid), unit=unit,
                  y_down=y_down, source="[columns] table", **names)
