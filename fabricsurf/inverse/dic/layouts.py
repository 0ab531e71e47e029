"""Column layouts of DIC point-cloud exports: which header names hold the coordinates, the
displacements and the lost-point flags, in which unit and axes, and whether the coordinates
are the reference (undeformed) or the deformed positions (docs/dic.md says where each layout
was read from and how it was checked).

A header cell may carry its unit, ``u [mm]`` or ``x (pixel)``: the name is what precedes the
bracket; the unit is checked against the declared one (:func:`split_unit`). A role may have
several accepted names (header generations of one program, e.g. MatchID's ``x`` and
``coor.X [mm]``): the first one the header has is used.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from fabricsurf.errors import DataError

Names = str | tuple[str, ...] | None
OPTIONAL = ("z", "w", "valid", "px", "py")
"""Roles a header may lack (the lost-point flags ``flag0``, ``flag1``, … too)."""
COORDINATES = ("reference", "deformed")


@dataclass(frozen=True)
class Layout:
    """Header names of one export layout. ``x``, ``y``, ``u``, ``v`` are required; ``z``, ``w``
    are used when the header has them. ``valid``/``invalid``: a column whose value ``invalid``
    marks a lost point (VIC and DICe write sigma = -1); ``flags``: further (column, value)
    pairs that do (DICe's MATCH = -1); ``zero_lost``: a row whose displacements are all
    exactly 0 is a lost point (DaVis writes zeros), unless every row of the image is.
    ``unit``: the coordinates' natural unit ("mm" or "pixel"); ``y_down``: image axes (y
    positive down). ``coordinates``: "reference" or "deformed" (then reference = deformed −
    displacement). ``px``/``py``: integer pixel positions of the points, used to match the
    points of two images. ``tags``: (role, unit) the [columns] table wrote into a name."""

    name: str
    x: Names
    y: Names
    u: Names
    v: Names
    z: Names = None
    w: Names = None
    valid: Names = None
    invalid: float | None = None
    unit: str = "mm"
    y_down: bool = False
    source: str = ""
    flags: tuple[tuple[str, float], ...] = ()
    zero_lost: bool = False
    coordinates: str = "reference"
    px: Names = None
    py: Names = None
    tags: tuple[tuple[str, str], ...] = ()

    def columns(self) -> dict[str, tuple[str, ...]]:
        """{role: accepted header names} of the required and optional columns."""
        roles = {r: getattr(self, r) for r in ("x", "y", "u", "v", "z", "w", "valid", "px", "py")}
        roles |= {f"flag{k}": name for k, (name, _) in enumerate(self.flags)}
        return {
            k: (v,) if isinstance(v, str) else tuple(v) for k, v in roles.items() if v is not None
        }

    def first(self, role: str) -> str:
        """The first accepted header name of ``role`` (what our generator writes)."""
        return self.columns()[role][0]

    def lost_flags(self) -> list[tuple[str, float]]:
        """(role, value) pairs marking a lost point."""
        out = [] if self.invalid is None else [("valid", self.invalid)]
        return out + [(f"flag{k}", value) for k, (_, value) in enumerate(self.flags)]


LAYOUTS = {
    "dice": Layout(
        "dice",
        "COORDINATE_X",
        "COORDINATE_Y",
        "DISPLACEMENT_X",
        "DISPLACEMENT_Y",
        valid="SIGMA",
        invalid=-1.0,
        flags=(("MATCH", -1.0),),
        unit="pixel",
        y_down=True,
        source="DICe solution files (DICe_solution_N.txt)",
    ),
    "dice_stereo": Layout(
        "dice_stereo",
        "MODEL_COORDINATES_X",
        "MODEL_COORDINATES_Y",
        "MODEL_DISPLACEMENT_X",
        "MODEL_DISPLACEMENT_Y",
        z="MODEL_COORDINATES_Z",
        w="MODEL_DISPLACEMENT_Z",
        valid="SIGMA",
        invalid=-1.0,
        flags=(("MATCH", -1.0),),
        unit="mm",
        y_down=True,
        source="DICe stereo solution files, MODEL_* columns",
    ),
    "matchid": Layout(
        "matchid",
        ("x", "coor.X"),
        ("y", "coor.Y"),
        ("u", "disp.Horizontal Displacement U"),
        ("v", "disp.Vertical Displacement V"),
        z=("z", "coor.Z"),
        w=("w", "disp.Out-Of-Plane: W"),
        unit="mm",
        y_down=True,
        coordinates="deformed",
        px=("x_pic", "Coordinates.Image X"),
        py=("y_pic", "Coordinates.Image Y"),
        source="MatchID CSV export",
    ),
    "davis": Layout(
        "davis",
        "x",
        "y",
        ("Vx", "U", "Dx"),
        ("Vy", "V", "Dy"),
        z="z",
        w=("Vz", "W", "Dz"),
        valid="isValid",
        invalid=0.0,
        zero_lost=True,
        unit="mm",
        coordinates="deformed",
        source="LaVision DaVis text export",
    ),
    "vic2d": Layout(
        "vic2d",
        "x",
        "y",
        "u",
        "v",
        valid="sigma",
        invalid=-1.0,
        unit="pixel",
        y_down=True,
        source="VIC-2D CSV export, image columns",
    ),
    "vic2d_metric": Layout(
        "vic2d_metric",
        "X",
        "Y",
        "U",
        "V",
        valid="sigma",
        invalid=-1.0,
        unit="mm",
        source="VIC-2D CSV export, calibrated columns",
    ),
    "vic3d": Layout(
        "vic3d",
        "X",
        "Y",
        "U",
        "V",
        z="Z",
        w="W",
        valid="sigma",
        invalid=-1.0,
        unit="mm",
        source="VIC-3D CSV export",
    ),
    "aramis_nodemap": Layout(
        "aramis_nodemap",
        "x_undef",
        "y_undef",
        "u",
        "v",
        z="z_undef",
        w="w",
        unit="mm",
        source="ZEISS GOM ARAMIS nodemap (aramis-data-exporter)",
    ),
}
"""The layouts read by name; any other through ``layout = "columns"`` and a [columns] table."""

UNITS = {
    "mm": "mm",
    "millimeter": "mm",
    "millimetre": "mm",
    "m": "m",
    "pixel": "pixel",
    "pixels": "pixel",
    "px": "pixel",
    "pix": "pixel",
}
"""Unit tags of header cells, normalised; other tags (%, 1, ...) are not length units."""
_TAG = re.compile(r"^(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")


def split_unit(cell: str) -> tuple[str, str | None]:
    """(name, unit tag or None) of a header cell: ``"u [mm]"`` → ("u", "mm")."""
    cell = cell.strip().strip('"').strip("'").strip()
    m = _TAG.match(cell)
    if not m:
        return cell, None
    return m.group(1).strip(), m.group(2).strip()


def guess_layout(names: set[str]) -> str | None:
    """The named layout whose required columns the header has (for a hint), or None."""
    for name, lay in LAYOUTS.items():
        cols = lay.columns()
        if all(any(n in names for n in cols[r]) for r in ("x", "y", "u", "v")):
            return name
    return None


KNOWN = {
    "x",
    "y",
    "u",
    "v",
    "z",
    "w",
    "valid",
    "invalid",
    "unit",
    "y_down",
    "coordinates",
    "pixel_x",
    "pixel_y",
}


def custom_layout(table: dict, where: str) -> Layout:
    """A layout from the [columns] table: x, y, u, v (required), z, w, valid, invalid,
    pixel_x, pixel_y (optional), unit ("mm" or "pixel"), y_down, coordinates ("reference",
    the default, or "deformed"). A name may carry its unit, ``x = "X [mm]"``: the tag is
    checked against the file's."""
    extra = sorted(set(table) - KNOWN)
    if extra:
        raise DataError(
            f"{where}: unknown key [columns] {extra[0]} (known: {', '.join(sorted(KNOWN))})"
        )
    names, tags = {}, []
    for key, role in (
        ("x", "x"),
        ("y", "y"),
        ("u", "u"),
        ("v", "v"),
        ("z", "z"),
        ("w", "w"),
        ("valid", "valid"),
        ("pixel_x", "px"),
        ("pixel_y", "py"),
    ):
        if key not in table:
            if key in "xyuv":
                raise DataError(
                    f'{where}: layout "columns" needs [columns] {key} = "header '
                    'name" (x, y, u, v required; z, w, valid optional)'
                )
            continue
        if not isinstance(table[key], str) or not table[key].strip():
            raise DataError(f"{where}: [columns] {key} = {table[key]!r} must be a header name")
        name, tag = split_unit(table[key])
        names[role] = name
        if tag is not None:
            tags.append((role, tag))
    invalid = table.get("invalid")
    if invalid is not None and (isinstance(invalid, bool) or not isinstance(invalid, (int, float))):
        raise DataError(f"{where}: [columns] invalid = {invalid!r} must be a number")
    if (invalid is None) != ("valid" not in names):
        raise DataError(
            f"{where}: [columns] valid and invalid go together (the column and "
            "the value in it that marks a lost point)"
        )
    unit = table.get("unit", "mm")
    if unit not in ("mm", "pixel"):
        raise DataError(f"{where}: [columns] unit = {unit!r} is not one of ['mm', 'pixel']")
    y_down = table.get("y_down", unit == "pixel")
    if not isinstance(y_down, bool):
        raise DataError(f"{where}: [columns] y_down = {y_down!r} must be true or false")
    coords = table.get("coordinates", "reference")
    if coords not in COORDINATES:
        raise DataError(
            f"{where}: [columns] coordinates = {coords!r} is not one of "
            f"{list(COORDINATES)} (are x, y the points' positions in the reference "
            "image, or in each image?)"
        )
    return Layout(
        "columns",
        invalid=None if invalid is None else float(invalid),
        unit=unit,
        y_down=y_down,
        source="[columns] table",
        coordinates=coords,
        tags=tuple(tags),
        **names,
    )
