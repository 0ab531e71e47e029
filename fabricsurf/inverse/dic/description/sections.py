"""The tables of ``dic.toml`` (docs/dic.md), each read and checked key by key with errors that
name the key: ``[export]`` (the layout and the image number of a file name), ``[units]``,
``[frame]``, ``[steps]`` and ``[specimen]``. :func:`~.spec.read_spec` puts them together."""

from __future__ import annotations

import math
import re
from dataclasses import replace

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import PluginSetup, choice_option, number_option
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.contract.data import FORCE_UNITS
from fabricsurf.inverse.dic.frame import GRIP_ANGLE, Frame
from fabricsurf.inverse.dic.layouts import COORDINATES, LAYOUTS, Layout, custom_layout

COORDINATE_SCALE = {"mm": 1.0, "m": 1000.0}
"""mm per unit of the coordinates given in mm or m ([units] coordinates; pixels: mm_per_pixel)."""


def _int_list(value, key: str, where: str, minimum: int = 0) -> list[int]:
    ok = isinstance(value, list) and all(
        isinstance(v, int) and not isinstance(v, bool) and v >= minimum for v in value
    )
    if not ok:
        raise DataError(f"{where}: {key} = {value!r} must be a list of integers ≥ {minimum}")
    return list(value)


def float_list(value, key: str, where: str, n: int) -> list[float]:
    """``value`` (the key ``key``) as ``n`` finite numbers, one per load step."""
    ok = isinstance(value, list) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value
    )
    if not ok:
        raise DataError(f"{where}: {key} = {value!r} must be a list of finite numbers")
    if len(value) != n:
        raise DataError(
            f"{where}: {key} has {len(value)} values, [steps] images has {n} (one "
            "value per load step)"
        )
    return [float(v) for v in value]


def steps_of(t: dict, where: str) -> tuple[list[int], list[int]]:
    """([steps] images, [steps] reference_images): one image per load step, in order, and the
    unloaded images, none of them both."""
    s = t.get("steps", {})
    if "images" not in s:
        raise DataError(
            f"{where}: missing key [steps] images (the image number of each load "
            "step, in the order of the steps)"
        )
    images = _int_list(s["images"], "[steps] images", where)
    if not images:
        raise DataError(f"{where}: [steps] images is empty")
    for k in range(1, len(images)):
        if images[k] <= images[k - 1]:
            raise DataError(
                f"{where}: [steps] images = {images}: steps out of order: step "
                f"{k + 1} is image {images[k]}, step {k} image {images[k - 1]} (the "
                "images of successive steps must be taken one after the other)"
            )
    refs = _int_list(s.get("reference_images", []), "[steps] reference_images", where)
    both = sorted(set(refs) & set(images))
    if both:
        raise DataError(f"{where}: image {both[0]} is in both [steps] images and reference_images")
    return images, refs


def frame_of(t: dict, where: str, layout: Layout, scale: float) -> tuple[Frame, str]:
    """(the camera frame of [frame] at ``scale`` mm per export unit, [frame] outside)."""
    f = t.get("frame", {})
    origin = f.get("origin", [0.0, 0.0])
    if not (
        isinstance(origin, list)
        and len(origin) == 2
        and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in origin
        )
    ):
        raise DataError(
            f"{where}: [frame] origin = {origin!r} must be [x, y] (the export's "
            "coordinates of the specimen point X = Y = 0)"
        )
    grip = choice_option(t, "frame", "grip", tuple(GRIP_ANGLE), "left", where)
    tilt = (
        number_option(t, "frame", "angle_deg", where, positive=False) if "angle_deg" in f else None
    )
    y_down = f.get("y_down", layout.y_down)
    if not isinstance(y_down, bool):
        raise DataError(f"{where}: [frame] y_down = {y_down!r} must be true or false")
    outside = choice_option(t, "frame", "outside", ("error", "drop"), "error", where)
    return Frame(scale, y_down, (float(origin[0]), float(origin[1])), grip, tilt), outside


def units_of(t: dict, where: str, layout: Layout) -> tuple[str, float, float]:
    """(coordinate unit, mm per export unit, N per force unit)."""
    u = t.get("units", {})
    unit = choice_option(t, "units", "coordinates", ("mm", "m", "pixel"), layout.unit, where)
    if unit == "pixel":
        if "mm_per_pixel" not in u:
            raise DataError(
                f"{where}: the coordinates are in pixels ({layout.name} layout"
                f"{'' if 'coordinates' not in u else ', [units] coordinates'}) but "
                "[units] mm_per_pixel is missing: give the scale (mm per pixel) "
                "from the calibration"
            )
        scale = number_option(t, "units", "mm_per_pixel", where)
    else:
        if "mm_per_pixel" in u:
            raise DataError(
                f"{where}: [units] mm_per_pixel is given but the coordinates are in "
                f'{unit}; remove it or set [units] coordinates = "pixel"'
            )
        scale = COORDINATE_SCALE[unit]
    force = choice_option(t, "units", "force", tuple(FORCE_UNITS), "N", where)
    return unit, scale, FORCE_UNITS[force]


def specimen_of(t: dict, where: str, plugin) -> PluginSetup:
    """The specimen ([specimen]) and the test's own options, checked by its ``plugin``."""
    length = number_option(t, "specimen", "length", where)
    width = number_option(t, "specimen", "width", where)
    angles = t.get("specimen", {}).get("fibre_angles_deg")
    if not (isinstance(angles, list) and len(angles) == 2):
        raise DataError(
            f"{where}: [specimen] fibre_angles_deg = {angles!r} must be a list of two angles"
        )
    angles = tuple(number_option({"s": {"a": a}}, "s", "a", where, positive=False) for a in angles)
    checks.fibre_angles(angles)
    setup = PluginSetup(plugin.name, length, width, angles, plugin.parse_options(t, 1.0, where))
    plugin.check_specimen(setup, where)
    return setup


def layout_of(t: dict, where: str) -> tuple[Layout, str]:
    """(the layout, the key that states its coordinates: [columns] or [export] coordinates,
    which overrides a named layout's)."""
    export = t.get("export", {})
    name = export.get("layout")
    if name == "columns":
        if "coordinates" in export:
            raise DataError(
                f'{where}: with layout = "columns" the coordinates are stated by '
                "[columns] coordinates, not [export] coordinates"
            )
        return custom_layout(t.get("columns", {}), where), "[columns] coordinates"
    if name not in LAYOUTS:
        raise DataError(
            f"{where}: [export] layout = {name!r} is not one of {sorted(LAYOUTS) + ['columns']}"
        )
    if "columns" in t:
        raise DataError(f'{where}: a [columns] table goes with [export] layout = "columns"')
    layout = LAYOUTS[name]
    if "coordinates" in export:
        coords = export["coordinates"]
        if coords not in COORDINATES:
            raise DataError(
                f"{where}: [export] coordinates = {coords!r} is not one of {list(COORDINATES)}"
            )
        layout = replace(layout, coordinates=coords)
    return layout, "[export] coordinates"


IMAGE_NUMBER = {"last": r".*(?<!\d)(\d+)", "first": r"\D*(\d+)"}
"""[export] image_number: which integer of a file's name (its stem) is the image number."""


def image_number_of(value, where: str) -> re.Pattern:
    """ "last" (default) or "first" integer of the file name, or a regular expression whose
    first group is the number (e.g. "-(\\d+)_" for VIC's Test-0012_0.csv)."""
    if not isinstance(value, str):
        raise DataError(
            f'{where}: [export] image_number = {value!r} must be "last", '
            '"first" or a regular expression with one group'
        )
    try:
        pattern = re.compile(IMAGE_NUMBER.get(value, value))
    except re.error as e:
        raise DataError(
            f"{where}: [export] image_number = {value!r} is not a regular expression ({e})"
        ) from None
    if pattern.groups < 1:
        raise DataError(
            f"{where}: [export] image_number = {value!r} needs a group, e.g. "
            '"-(\\d+)_", around the image number'
        )
    return pattern
