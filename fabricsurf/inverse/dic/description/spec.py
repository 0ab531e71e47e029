"""The import description, ``dic.toml`` (docs/dic.md): which files, which layout, the camera
frame, the image-to-step mapping, binning; checked key by key, each error naming the key (its
tables: :mod:`.sections`), into an :class:`ImportSpec`."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from fabricsurf.errors import DataError
from fabricsurf.experiments import get_test
from fabricsurf.experiments.base import PluginSetup, number_option
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.contract.tables import read_toml
from fabricsurf.inverse.dic.description.sections import (
    float_list,
    frame_of,
    image_number_of,
    layout_of,
    specimen_of,
    steps_of,
    units_of,
)
from fabricsurf.inverse.dic.encoding import normalise
from fabricsurf.inverse.dic.frame import Frame
from fabricsurf.inverse.dic.layouts import Layout

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
    layout, coordinates_key = layout_of(t, where)
    files = t.get("export", {}).get("files")
    if not isinstance(files, str) or not files.strip():
        raise DataError(
            f"{where}: [export] files = {files!r} must be a file pattern, relative "
            "to the directory of this file or absolute, e.g. "
            '"DICe_solution_*.txt"'
        )
    encoding = normalise(t.get("export", {}).get("encoding"), where)
    image_number = image_number_of(t.get("export", {}).get("image_number", "last"), where)
    unit, scale, fscale = units_of(t, where, layout)
    frame, outside = frame_of(t, where, layout, scale)
    images, refs = steps_of(t, where)
    s = t["steps"]
    if "path" not in s:
        raise DataError(
            f"{where}: missing key [steps] path (the load-path value of each step:"
            " the grip displacement in mm for a bias test)"
        )
    load = float_list(s["path"], "[steps] path", where, len(images))
    force = (
        None
        if "force" not in s
        else [f * fscale for f in float_list(s["force"], "[steps] force", where, len(images))]
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
    setup = specimen_of(t, where, plugin)
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
