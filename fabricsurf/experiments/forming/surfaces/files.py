"""Triangulated tools from files: STL (ASCII and binary) and Wavefront OBJ, in the units the
user states, converted to mm (the package's length unit), welded and checked
(topology.check: closed, consistently and outwards oriented, no degenerate triangle).

A binary STL is an 80-byte header, the triangle count (uint32) and 50 bytes per triangle (the
normal and the three corners as float32, an attribute uint16); a file of exactly that size is
read as binary, any other as ASCII (``solid`` … ``facet normal`` … ``vertex x y z`` …). The
normals written in an STL file are ignored: the orientation is the corners' order (right-hand
rule), which is what the checks read. An OBJ file's ``v`` lines are the vertices and its ``f``
lines the faces (1-based indices, negative ones counted from the end, ``i/t/n`` forms allowed);
polygons are split into fans of triangles. The forming plug-in's ``punch_file``, ``die_file``,
``holder_file`` and their units are checked and read here too (:func:`tool_file_options`).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import numpy as np

from fabricsurf.errors import DataError, InputError
from fabricsurf.experiments.forming.surfaces import topology
from fabricsurf.experiments.forming.surfaces.triangulated import TriangulatedSurface

UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
"""Length units a tool file may be in, and their size in mm."""
TOOL_FILES_KEPT = 3
"""Tool files whose surfaces :func:`read_tool_file` keeps once read."""
TOOLS = ("punch", "die", "holder")
"""The tools a file may give."""
FILE_KEYS = {
    "punch_file": "the punch as a closed surface, an STL or OBJ file (path relative to "
    "experiment.toml; its pole at z = 0, moving up along z; default: the hemisphere of "
    "radius punch_radius)",
    "punch_units": "length unit of punch_file's coordinates (mm, cm, m or in; required "
    "with punch_file)",
    "die_file": "the die as a closed surface, an STL or OBJ file (path relative to "
    "experiment.toml; fixed, above the blank, its face where the holder presses the flange "
    "at z = 0; default: the plate with the opening and lip of the keys above)",
    "die_units": "length unit of die_file's coordinates (mm, cm, m or in; required with die_file)",
    "holder_file": "the blank holder as a closed surface, an STL or OBJ file (path relative to "
    "experiment.toml; fixed, below the blank, its face where it presses the flange at z = 0, "
    "placed holder_gap below; default: the plate about the opening, pressing from one lip "
    "radius beyond the die's lip)",
    "holder_units": "length unit of holder_file's coordinates (mm, cm, m or in; required with "
    "holder_file)",
}
"""The ``[tooling]`` keys of tools given as files (:func:`tool_file_options`)."""
_FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def unit_scale(units: str, path: str | Path) -> float:
    """mm per ``units`` (one of :data:`UNITS`; ``path`` names the source in the message)."""
    if units not in UNITS:
        raise InputError(f"{path}: units = {units!r} is not one of {sorted(UNITS)}")
    return UNITS[units]


def read_stl_triangles(path: str | Path) -> np.ndarray:
    """The corners (f, 3, 3) of the triangles of an STL file, ASCII or binary."""
    data = Path(path).read_bytes()
    if len(data) >= 84:
        count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        if len(data) == 84 + 50 * count:
            rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
            return np.frombuffer(data, dtype=rec, count=count, offset=84)["v"].astype(float)
    text = data.decode("ascii", errors="replace")
    if not text.lstrip().lower().startswith("solid"):
        raise InputError(f"{path}: neither a binary STL (size) nor an ASCII one ('solid …')")
    values = re.findall(rf"vertex\s+({_FLOAT})\s+({_FLOAT})\s+({_FLOAT})", text)
    if not values or len(values) % 3:
        raise InputError(f"{path}: {len(values)} 'vertex' lines, not a positive multiple of 3")
    return np.array(values, float).reshape(-1, 3, 3)


def read_obj_mesh(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, triangles) of an OBJ file (module docstring)."""
    vertices, faces = [], []
    for number, line in enumerate(Path(path).read_text(errors="replace").splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                vertices.append([float(t) for t in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(t.split("/")[0]) for t in parts[1:]]
                idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
                faces += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
        except ValueError as err:
            raise InputError(f"{path}, line {number}: cannot read {line.strip()!r}") from err
    faces = np.array(faces, dtype=np.int64).reshape(-1, 3)
    if not len(faces) or faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"{path}: no faces, or a face refers to a vertex that is not there")
    return np.array(vertices, float), faces


def read_surface(path: str | Path, units: str, closed: bool = True) -> TriangulatedSurface:
    """The tool surface of an STL or OBJ file whose coordinates are in ``units`` (one of
    :data:`UNITS`; no default: a file carries no units), in mm."""
    path = Path(path)
    scale = unit_scale(units, path)
    suffix = path.suffix.lower()
    if suffix == ".stl":
        corners = read_stl_triangles(path)
        points, faces = corners.reshape(-1, 3), np.arange(3 * len(corners)).reshape(-1, 3)
    elif suffix == ".obj":
        points, faces = read_obj_mesh(path)
    else:
        raise InputError(f"{path}: a tool surface is read from .stl or .obj, not {suffix!r}")
    vertices, faces = topology.weld(scale * points, faces)
    return TriangulatedSurface(vertices, faces, str(path), closed)


def write_stl(
    path: str | Path, vertices: np.ndarray, faces: np.ndarray, binary: bool = True
) -> None:
    """Write a triangle mesh as an STL file (normals by the right-hand rule)."""
    corners = np.asarray(vertices, float)[np.asarray(faces)]
    normals, _ = topology.face_normals(np.asarray(vertices, float), np.asarray(faces))
    normals = np.nan_to_num(normals)
    if binary:
        rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
        out = np.zeros(len(corners), dtype=rec)
        out["n"], out["v"] = normals, corners
        head = b"fabricsurf".ljust(80, b" ") + np.uint32(len(corners)).tobytes()
        Path(path).write_bytes(head + out.tobytes())
        return
    lines = ["solid tool"]
    for n, c in zip(normals, corners, strict=True):
        lines += [f"  facet normal {n[0]:.9e} {n[1]:.9e} {n[2]:.9e}", "    outer loop"]
        lines += [f"      vertex {p[0]:.15e} {p[1]:.15e} {p[2]:.15e}" for p in c]
        lines += ["    endloop", "  endfacet"]
    Path(path).write_text("\n".join([*lines, "endsolid tool", ""]))


def write_obj(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Write a triangle mesh as an OBJ file."""
    lines = [f"v {p[0]:.15e} {p[1]:.15e} {p[2]:.15e}" for p in np.asarray(vertices, float)]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(faces)]
    Path(path).write_text("\n".join([*lines, ""]))


def tool_file_options(tooling: dict, where: str) -> dict:
    """The tools' file keys (:data:`FILE_KEYS`: ``punch_file``, ``die_file``, ``holder_file`` and
    their units)
    checked, each file read once (its surface's own checks: closed, oriented, not degenerate,
    surfaces/topology.py) so that a bad file is refused with the data; the plug-in's tools and
    checks then take the same surfaces (:func:`given_surface`)."""
    out = {}
    for tool in TOOLS:
        out.update(_file_option(tooling, where, tool))
    return out


def _file_option(tooling: dict, where: str, tool: str) -> dict:
    """``{tool}_file`` and ``{tool}_units`` checked, the file read."""
    key, unit_key = f"{tool}_file", f"{tool}_units"
    path, units = tooling.get(key), tooling.get(unit_key)
    if path is None:
        if units is not None:
            raise DataError(f"{where}: [tooling] {unit_key} = {units!r} without {key}")
        return {}
    if not isinstance(path, str) or not path.strip():
        raise DataError(
            f'{where}: [tooling] {key} = {path!r} must be a file name in quotes, e.g. "{tool}.stl"'
        )
    if units not in UNITS:
        raise DataError(
            f"{where}: [tooling] {key} = {path!r} needs {unit_key}, the unit of its "
            f"coordinates (one of {', '.join(UNITS)}; a file carries none), "
            + ("none given" if units is None else f"got {units!r}")
        )
    if not Path(path).is_file():
        raise DataError(f"{where}: [tooling] {key}: {path}: no such file")
    read_tool_file(path, units)
    return {key: str(path), unit_key: units}


def given_surface(o: dict, tool: str):
    """The ``tool`` (punch, die or holder) surface the options give: a surface object
    (``{tool}_surface``, Python), the file's (``{tool}_file``), or None (the analytic tool)."""
    if o.get(f"{tool}_surface") is not None or not o.get(f"{tool}_file"):
        return o.get(f"{tool}_surface")
    return read_tool_file(o[f"{tool}_file"], o[f"{tool}_units"])


def punch_surface(o: dict):
    """The punch surface of the options (:func:`given_surface`), or None: the hemisphere."""
    return given_surface(o, "punch")


def read_tool_file(path: str | Path, units: str) -> TriangulatedSurface:
    """:func:`read_surface`, once for a file as it stands (its resolved path, modification time
    and size): the options' check, the tools, the die and symmetry checks and the data's check
    all ask for the punch and the die, and a file of 6·10⁶ triangles takes about a minute to
    read."""
    resolved = Path(path).resolve()
    stat = resolved.stat()
    return _read_once(str(path), str(resolved), units, (stat.st_mtime_ns, stat.st_size))


@functools.lru_cache(maxsize=TOOL_FILES_KEPT)
def _read_once(path: str, resolved: str, units: str, stamp: tuple) -> TriangulatedSurface:
    """The file at ``path`` read (``resolved`` and ``stamp`` only tell files apart)."""
    return read_surface(path, units)
