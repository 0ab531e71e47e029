"""The import description, ``dic.toml`` (docs/dic.md): which files, which layout, the camera
frame, the image-to-step mapping, binning; checked key by key, each error naming the key."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

from fabricsurf.errors import DataError
from fabricsurf.experiments import get_test
from fabricsurf.experiments.base import PluginSetup, choice_option, number_option
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.contract.data import FORCE_UNITS
from fabricsurf.inverse.contract.tables import read_toml
from fabricsurf.inverse.dic.encoding import normalise
from fabricsurf.inverse.dic.frame import GRIP_ANGLE, Frame
from fabricsurf.inverse.dic.layouts import COORDINATES, LAYOUTS, Layout, custom_layout

KEYS = {
    "": {
        "name",
        "export",
        "columns",
        "units",
        "frame",
        "specimen",
        "loading",
        "steps",
        "binning",
        "data",
        "source",
        "material",
    },
    "export": {"layout", "files", "image_number", "encoding", "coordinates"},
    "units": {"coordinates", "mm_per_pixel", "force"},
    "frame": {"origin", "grip", "angle_deg", "y_down", "outside"},
    "steps": {"images", "reference_images", "path", "force"},
    "binning": {"pitch", "min_points"},
    "data": {"noise_std", "force_noise_std"},
}
COORDINATE_SCALE = {"mm": 1.0, "m": 1000.0}


@dataclass
class ImportSpec:
    """A checked dic.toml: lengths in mm, forces in N."""

    where: str
    name: str
    layout: Layout
    files: str
    image_number: re.Pattern
    root: Path
    frame: Frame
    outside: str
    setup: PluginSetup
    images: list[int]
    reference_images: list[int]
    path: list[float]
    force: list[float] | None
    pitch: float | None
    min_points: int
    noise_std: float | None
    force_noise_std: float | None
    source: dict
    unit: str
    encoding: str | None = None
    coordinates_key: str = "[export] coordinates"


def _check_keys(t: dict, where: str, plugin) -> None:
    allowed = {k: set(v) for k, v in KEYS.items()}
    for table, keys in plugin.keys.items():
        allowed.setdefault(table, set()).update(keys)
        allowed[""].add(table)
    allowed.setdefault("specimen", set()).update({"length", "width", "fibre_angles_deg"})
    allowed["loading"] = allowed.get("loading", set()) | {"test"}
    for key, value in t.items():
        if key not in allowed[""]:
            raise DataError(
                f"{where}: unknown key or table '{key}' (known: {', '.join(sorted(allowed['']))})"
            )
        if key in allowed and key not in ("", "columns", "source") and isinstance(value, dict):
            extra = sorted(set(value) - allowed[key])
            if extra:
                raise DataError(
                    f"{where}: unknown key [{key}] {extra[0]} (known: "
                    f"{', '.join(sorted(allowed[key]))})"
                )


def _int_list(value, key: str, where: str, minimum: int = 0) -> list[int]:
    ok = isinstance(value, list) and all(
        isinstance(v, int) and not isinstance(v, bool) and v >= minimum for v in value
    )
    if not ok:
        raise DataError(f"{where}: {key} = {value!r} must be a list of integers ≥ {minimum}")
    return list(value)


def _float_list(value, key: str, where: str, n: int) -> list[float]:
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


def _steps(t: dict, where: str) -> tuple[list[int], list[int]]:
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


def _frame(t: dict, where: str, layout: Layout, scale: float) -> tuple[Frame, str]:
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


def _units(t: dict, where: str, layout: Layout) -> tuple[str, float, float]:
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


def _setup(t: dict, where: str, plugin) -> PluginSetup:
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


def _layout(t: dict, where: str) -> tuple[Layout, str]:
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


def _image_number(value, where: str) -> re.Pattern:
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


def read_spec(path: str | Path) -> ImportSpec:
    """Read and check dic.toml (lengths in mm: the specimen, path and pitch are in mm)."""
    path = Path(path)
    where = path.name
    t = read_toml(path)
    test = t.get("loading", {}).get("test")
    try:
        plugin = get_test(test)
    except DataError as e:
        raise DataError(str(e).replace("experiment.toml", where)) from None
    _check_keys(t, where, plugin)
    layout, coordinates_key = _layout(t, where)
    files = t.get("export", {}).get("files")
    if not isinstance(files, str) or not files.strip():
        raise DataError(
            f"{where}: [export] files = {files!r} must be a file pattern, relative "
            "to the directory of this file or absolute, e.g. "
            '"DICe_solution_*.txt"'
        )
    encoding = normalise(t.get("export", {}).get("encoding"), where)
    image_number = _image_number(t.get("export", {}).get("image_number", "last"), where)
    unit, scale, fscale = _units(t, where, layout)
    frame, outside = _frame(t, where, layout, scale)
    images, refs = _steps(t, where)
    s = t["steps"]
    if "path" not in s:
        raise DataError(
            f"{where}: missing key [steps] path (the load-path value of each step:"
            " the grip displacement in mm for a bias test)"
        )
    load = _float_list(s["path"], "[steps] path", where, len(images))
    force = (
        None
        if "force" not in s
        else [f * fscale for f in _float_list(s["force"], "[steps] force", where, len(images))]
    )
    if force is not None and not plugin.has_reaction:
        raise DataError(f"{where}: [steps] force: the '{plugin.name}' test measures no reaction")
    if force is not None:
        fnoise = t.get("data", {}).get("force_noise_std")
        checks.tensile_forces(
            plugin,
            images,
            force,
            f"{where}: [steps] force",
            None if not isinstance(fnoise, (int, float)) else fnoise * fscale,
            "image",
        )
    b = t.get("binning", {})
    pitch = number_option(t, "binning", "pitch", where) if "pitch" in b else None
    setup = _setup(t, where, plugin)
    if pitch is not None and pitch > 0.5 * min(setup.length, setup.width):
        raise DataError(
            f"{where}: [binning] pitch = {pitch:g} mm is more than half the "
            f"specimen's {min(setup.length, setup.width):g} mm side: the field would "
            "be one or two points across it (the pitch is in mm, like the specimen)"
        )
    min_points = b.get("min_points", 1)
    if isinstance(min_points, bool) or not isinstance(min_points, int) or min_points < 1:
        raise DataError(f"{where}: [binning] min_points = {min_points!r} must be an integer ≥ 1")
    noise = {
        k: number_option(t, "data", k, where) if k in t.get("data", {}) else None
        for k in ("noise_std", "force_noise_std")
    }
    name = t.get("name", path.parent.name)
    if not isinstance(name, str) or not name.strip():
        raise DataError(f"{where}: name = {name!r} must be a non-empty string")
    source = t.get("source", {})
    if not isinstance(source, dict) or any(not isinstance(v, str) for v in source.values()):
        raise DataError(f'{where}: [source] holds free text only (key = "text")')
    return ImportSpec(
        where,
        name,
        layout,
        files,
        image_number,
        path.parent,
        frame,
        outside,
        setup,
        images,
        refs,
        load,
        force,
        pitch,
        min_points,
        noise["noise_std"],
        None if noise["force_noise_std"] is None else noise["force_noise_std"] * fscale,
        dict(source),
        unit,
        encoding,
        coordinates_key,
    )
