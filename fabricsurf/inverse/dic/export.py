"""Writing a synthetic DIC export in one of the layouts (the generator of the tests and of
demos/demo_dic.py): per-image files in the camera's frame and unit, with holes, laid out as
the vendor's documentation shows (docs/dic.md): DICe's ``***`` preamble, VIC's quoted CSV
header, the ARAMIS nodemap's ``#`` header with unit tags and semicolons, DaVis's ``#DaVis``
line with quoted, tagged names and semicolons (zeros and isValid = 0 for lost points);
deformed coordinates (x + u) for the layouts that export them. ``write_dice_solution``
writes DICe's solution files as DICe does (its header line and columns, %.4E): the 2-D file
without SIGMA (MATCH = -1 on lost subsets) and the stereo file with MODEL_* columns."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.inverse.dic.frame import Frame
from fabricsurf.inverse.dic.layouts import Layout

FILE_NAMES = {"dice": "DICe_solution_{:02d}.txt", "aramis_nodemap": "nodemap_stage_{:04d}.txt"}


def _header(layout: Layout, roles: list[str], unit: str) -> tuple[str, str]:
    """(preamble + header text, delimiter) as the layout's files have them."""
    names = [layout.first(r) for r in roles]
    if layout.name == "dice":
        pre = (
            "***\n*** Digital Image Correlation Engine (DICe) -- synthetic export\n***\n"
            "*** Coordinates given with (0,0) as upper left corner of image, x positive "
            "right, y positive down\n***\n"
        )
        return pre + ",".join(names) + "\n", ","
    if layout.name == "aramis_nodemap":
        tagged = [f"{n} [{unit}]" if r in "xyzuvw" else n for r, n in zip(roles, names)]
        return (
            "# Process data:\n# specimen : synthetic\n"
            + "#" * 40
            + "\n# "
            + "; ".join(["ID", *tagged])
            + "\n"
        ), ";"
    if layout.name == "davis":
        tagged = [f'"{n} [{unit}]"' if r in "xyzuvw" else f'"{n}"' for r, n in zip(roles, names)]
        return f"#DaVis 10.x 2C vector field 4 1 1 {';'.join(tagged)}\n", ";"
    if layout.name.startswith("vic"):
        return ", ".join(f'"{n}"' for n in names) + "\n", ","
    return ",".join(names) + "\n", ","


def write_images(
    directory: str | Path,
    layout: Layout,
    frame: Frame,
    images: list[int],
    X: np.ndarray,
    displacements: list[np.ndarray],
    holes: float = 0.0,
    seed: int = 0,
    w: list[np.ndarray] | None = None,
) -> list[Path]:
    """One file per image: the specimen points ``X`` (n × 2, mm) and each image's
    displacements (n × 2, mm), written in ``layout`` in the camera ``frame`` (its unit: mm per
    export unit = ``frame.scale``), deformed coordinates x + u for a layout that exports them,
    pixel positions (20 per mm of X) for a layout with pixel columns, and ``w`` (one array per
    image, export unit) as its out-of-plane column when given. A fraction ``holes`` of the
    points of each image is lost: the layout's flag (sigma = -1, isValid = 0) with zero
    displacements, or NaN cells. Returns the files."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    x, y = frame.inverse_points(X[:, 0], X[:, 1])
    pixels = ["px", "py"] if layout.px else []
    roles = (
        pixels
        + ["x", "y", "u", "v"]
        + (["w"] if w is not None else [])
        + (["valid"] if layout.valid else [])
    )
    unit = "pixel" if frame.scale != 1.0 else "mm"
    head, delim = _header(layout, roles, unit)
    pattern = FILE_NAMES.get(layout.name, "export_{:03d}.csv")
    out = []
    for k, (image, U) in enumerate(zip(images, displacements)):
        u, v = frame.inverse_vectors(U[:, 0], U[:, 1])
        lost = rng.random(len(x)) < holes
        flagged = layout.valid is not None or layout.zero_lost
        u, v = (np.where(lost, 0.0 if flagged else np.nan, c) for c in (u, v))
        moved = layout.coordinates == "deformed"
        cols = [np.rint(20 * X[:, 0]), np.rint(20 * X[:, 1])] if pixels else []
        cols += [
            x + np.nan_to_num(u) if moved else x,
            y + np.nan_to_num(v) if moved else y,
            u,
            v,
        ] + ([w[k]] if w is not None else [])
        if layout.valid:
            cols.append(np.where(lost, layout.invalid, 1.0 if layout.invalid == 0 else 0.01))
        table = np.column_stack(cols)
        if layout.name == "aramis_nodemap":
            table = np.column_stack([np.arange(1, len(x) + 1), table])
        path = d / pattern.format(image)
        with open(path, "w") as fh:
            fh.write(head)
            np.savetxt(fh, table, fmt="%.10g", delimiter=delim)
        out.append(path)
    return out


def spec_text(
    frame: Frame,
    *,
    name: str,
    layout: str,
    files: str,
    length: float,
    width: float,
    images: list[int],
    path: list[float],
    reference_images: list[int] | None = None,
    pitch: float | None = None,
    fibre_angles_deg: tuple[float, float] = (45.0, -45.0),
) -> str:
    """The ``dic.toml`` of a bias test exported by ``write_images`` in ``frame``
    (docs/dic.md): the camera-to-specimen map, the specimen, the images with their grip
    displacements ``path`` (mm) and, with ``pitch``, binning."""
    lines = [
        f'name = "{name}"',
        "[export]",
        f'layout = "{layout}"',
        f'files = "{files}"',
        "[units]",
        f"mm_per_pixel = {frame.scale}",
        "[frame]",
        f"origin = [{frame.origin[0]}, {frame.origin[1]}]",
        f'grip = "{frame.grip}"',
        f"y_down = {str(frame.y_down).lower()}",
    ]
    if frame.tilt_deg is not None:
        lines.append(f"angle_deg = {frame.tilt_deg}")
    lines += [
        "[specimen]",
        f"length = {length}",
        f"width = {width}",
        f"fibre_angles_deg = [{fibre_angles_deg[0]}, {fibre_angles_deg[1]}]",
        "[loading]",
        'test = "bias_extension"',
        "[steps]",
    ]
    if reference_images is not None:
        lines.append(f"reference_images = {list(reference_images)}")
    lines += [f"images = {list(images)}", f"path = {[float(p) for p in path]}"]
    if pitch:
        lines += ["[binning]", f"pitch = {pitch}"]
    return "\n".join(lines) + "\n"


DICE_2D = (
    "SUBSET_ID",
    "COORDINATE_X",
    "COORDINATE_Y",
    "CROSS_CORR_Q",
    "CROSS_CORR_R",
    "DISPLACEMENT_X",
    "DISPLACEMENT_Y",
    "VSG_STRAIN_XX",
    "VSG_STRAIN_YY",
    "VSG_STRAIN_XY",
    "NLVC_STRAIN_XX",
    "NLVC_STRAIN_YY",
    "NLVC_STRAIN_XY",
    "GAMMA",
    "MATCH",
)
"""The columns of a DICe 2-D solution file without SIGMA (MATCH = -1 on a lost subset)."""
DICE_STEREO = (
    "SUBSET_ID",
    "COORDINATE_X",
    "COORDINATE_Y",
    "DISPLACEMENT_X",
    "DISPLACEMENT_Y",
    "MODEL_COORDINATES_X",
    "MODEL_COORDINATES_Y",
    "MODEL_COORDINATES_Z",
    "MODEL_DISPLACEMENT_X",
    "MODEL_DISPLACEMENT_Y",
    "MODEL_DISPLACEMENT_Z",
    "SIGMA",
)
"""The columns of a DICe stereo solution file (MODEL_* in the calibration's unit)."""


def dice_printed(a: np.ndarray) -> np.ndarray:
    """``a`` as a DICe solution file prints it (%.4E) and reads back."""
    return np.array([float(f"{v:.4E}") for v in np.ravel(a)]).reshape(np.shape(a))


def write_dice_solution(
    path: str | Path, columns: tuple[str, ...], values: dict[str, np.ndarray]
) -> Path:
    """A DICe solution file as DICe writes it without preamble: the comma-separated header
    line ``columns`` (DICE_2D, DICE_STEREO), one row per subset, SUBSET_ID 0, 1, … as an
    integer and every other value in %.4E (``dice_printed``); a column absent from
    ``values`` is written as 0."""
    n = len(next(iter(values.values())))
    table = np.column_stack([values.get(c, np.zeros(n)) for c in columns[1:]])
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(
        ",".join(columns)
        + "\n"
        + "".join(f"{k}," + ",".join(f"{v:.4E}" for v in row) + "\n" for k, row in enumerate(table))
    )
    return p
