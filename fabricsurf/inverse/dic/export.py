"""Writing a synthetic DIC export in one of the layouts (the generator of the tests and of
demos/demo_dic.py): per-image files in the camera's frame and unit, with holes, laid out as
the vendor's documentation shows (docs/dic.md): DICe's ``***`` preamble, VIC's quoted CSV
header, the ARAMIS nodemap's ``#`` header with unit tags and semicolons."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.inverse.dic.frame import Frame
from fabricsurf.inverse.dic.layouts import Layout

FILE_NAMES = {"dice": "DICe_solution_{:02d}.txt", "aramis_nodemap": "nodemap_stage_{:04d}.txt"}


def _header(layout: Layout, roles: list[str], unit: str) -> tuple[str, str]:
    """(preamble + header text, delimiter) as the layout's files have them."""
    names = [getattr(layout, r) for r in roles]
    if layout.name == "dice":
        pre = ("***\n*** Digital Image Correlation Engine (DICe) -- synthetic export\n***\n"
               "*** Coordinates given with (0,0) as upper left corner of image, x positive "
               "right, y positive down\n***\n")
        return pre + ",".join(names) + "\n", ","
    if layout.name == "aramis_nodemap":
        tagged = [f"{n} [{unit}]" if r in "xyzuvw" else n for r, n in zip(roles, names)]
        return ("# Process data:\n# specimen : synthetic\n" + "#" * 40 + "\n# "
                + "; ".join(["ID", *tagged]) + "\n"), ";"
    if layout.name.startswith("vic"):
        return ", ".join(f'"{n}"' for n in names) + "\n", ","
    return ",".join(names) + "\n", ","


def write_images(directory: str | Path, layout: Layout, frame: Frame, images: list[int],
                 X: np.ndarray, displacements: list[np.ndarray], holes: float = 0.0,
                 seed: int = 0) -> list[Path]:
    """One file per image: the specimen points ``X`` (n × 2, mm) and each image's
    displacements (n × 2, mm), written in ``layout`` in the camera ``frame`` (its unit: mm per
    export unit = ``frame.scale``). A fraction ``holes`` of the points of each image is lost:
    sigma = -1 (layouts with a validity column) or NaN cells. Returns the files."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    x, y = frame.inverse_points(X[:, 0], X[:, 1])
    roles = ["x", "y", "u", "v"] + (["valid"] if layout.valid else [])
    unit = "pixel" if frame.scale != 1.0 else "mm"
    head, delim = _header(layout, roles, unit)
    pattern = FILE_NAMES.get(layout.name, "export_{:03d}.csv")
    out = []
    for image, U in zip(images, displacements):
        u, v = frame.inverse_vectors(U[:, 0], U[:, 1])
        cols = [x, y, u, v]
        lost = rng.random(len(x)) < holes
        if layout.valid:
            cols.append(np.where(lost, layout.invalid, 0.01))
            cols[2], cols[3] = np.where(lost, 0.0, u), np.where(lost, 0.0, v)
        else:
            cols[2], cols[3] = np.where(lost, np.nan, u), np.where(lost, np.nan, v)
        table = np.column_stack(cols)
        if layout.name == "aramis_nodemap":
            table = np.column_stack([np.arange(1, len(x) + 1), table])
        path = d / pattern.format(image)
        with open(path, "w") as fh:
            fh.write(head)
            np.savetxt(fh, table, fmt="%.10g", delimiter=delim)
        out.append(path)
    return out


def spec_text(frame: Frame, *, name: str, layout: str, files: str, length: float, width: float,
              images: list[int], path: list[float], reference_images: list[int] | None = None,
              pitch: float | None = None,
              fibre_angles_deg: tuple[float, float] = (45.0, -45.0)) -> str:
    """The ``dic.toml`` of a bias test exported by ``write_images`` in ``frame``
    (docs/dic.md): the camera-to-specimen map, the specimen, the images with their grip
    displacements ``path`` (mm) and, with ``pitch``, binning."""
    lines = [f'name = "{name}"', "[export]", f'layout = "{layout}"', f'files = "{files}"',
             "[units]", f"mm_per_pixel = {frame.scale}", "[frame]",
             f"origin = [{frame.origin[0]}, {frame.origin[1]}]", f'grip = "{frame.grip}"',
             f"y_down = {str(frame.y_down).lower()}"]
    if frame.tilt_deg is not None:
        lines.append(f"angle_deg = {frame.tilt_deg}")
    lines += ["[specimen]", f"length = {length}", f"width = {width}",
              f"fibre_angles_deg = [{fibre_angles_deg[0]}, {fibre_angles_deg[1]}]",
              "[loading]", 'test = "bias_extension"', "[steps]"]
    if reference_images is not None:
        lines.append(f"reference_images = {list(reference_images)}")
    lines += [f"images = {list(images)}", f"path = {[float(p) for p in path]}"]
    if pitch:
        lines += ["[binning]", f"pitch = {pitch}"]
    return "\n".join(lines) + "\n"
