"""DIC exports → an :class:`~fabricsurf.inverse.contract.experiment.Experiment` (docs/dic.md).

One file per image; the image number is an integer of the file's name (the last by default,
``[export] image_number``). Each image is read, its holes (NaN or empty cells, the layout's
lost-point flags) dropped and counted, its coordinates checked against the first image read
(reference or deformed, :mod:`~fabricsurf.inverse.dic.coordinates`) and made reference ones,
its points moved to the specimen's frame, checked (duplicates, outline) and, with a pitch,
binned before the next is read: the memory is that of one image, the first image's points and
the binned result.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.errors import DataError
from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.dic import coordinates
from fabricsurf.inverse.dic.binning import bin_points
from fabricsurf.inverse.dic.config import ImportSpec
from fabricsurf.inverse.dic.files import image_files
from fabricsurf.inverse.dic.layouts import UNITS
from fabricsurf.inverse.dic.noise import noise
from fabricsurf.inverse.dic.reader import ExportFile, read_export

OUTLINE_TOL = 1e-6
"""Points this far outside the specimen (relative to its size) still count as on it."""
MAX_DISPLACEMENT = 10.0
"""Displacements beyond this many specimen sizes are a unit mix-up (the contract's limit,
checks.field_displacements, here with the export's file and line)."""


def _check_units(f: ExportFile, unit: str) -> None:
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


def _valid(f: ExportFile, spec: ImportSpec, d: int) -> np.ndarray:
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


def _image(
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


class _Reading:
    """What persists from image to image: the first image read (the coordinates check's
    anchor) and the evidence of the others."""

    def __init__(self) -> None:
        self.anchor: coordinates.Anchor | None = None
        self.evidence: list[dict] = []
        self.dropped: dict[str, str] = {}
        self.read = 0
        self.total = 0
        self.pending: DataError | None = None
        """An error of the first image (off the specimen, a tilt, …), raised after the second
        image has shown whether the coordinates were read as what they are: a wrong reading
        misplaces the points, and its evidence is the message that helps."""


def _read(
    spec: ImportSpec, path, image: int, d: int, state: _Reading
) -> tuple[ExportFile, np.ndarray, dict]:
    """One image read, its valid rows, and its coordinates checked and made reference."""
    f = read_export(path, image, spec.layout, spec.encoding)
    state.read += 1
    _check_units(f, spec.unit)
    ok = _valid(f, spec, d)
    extra = {"encoding": f.encoding.label}
    if state.anchor is None:
        state.anchor = coordinates.anchor(image, path.name, f.data, ok)
    else:
        state.evidence.append(
            coordinates.compare(
                state.anchor,
                image,
                path.name,
                f.data,
                ok,
                spec.layout.coordinates,
                spec.coordinates_key,
            )
        )
    if spec.layout.coordinates == "deformed":
        coordinates.to_reference(f.data)
    if d == 2 and "w" in f.data:
        state.dropped["w"] = (
            f"planar test: the out-of-plane displacement column {f.names['w']!r} is not used"
        )
    return f, ok, extra


def _collect(
    spec: ImportSpec,
    files: dict,
    images: list[int],
    d: int,
    tilt_first: bool,
    report: list,
    state: _Reading,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(step, X, u) of ``images`` (steps numbered from 1 in their order), binned when a
    pitch is given; one entry per image appended to ``report``."""
    steps, Xs, us = [], [], []
    for k, image in enumerate(images, start=1):
        f, ok, extra = _read(spec, files[image], image, d, state)
        if state.pending is not None:
            raise state.pending
        try:
            X, u, counts = _image(f, spec, d, tilt_first and k == 1, ok)
            if k == 1 and len(X):
                _extent(files[image].name, X, spec)
            _not_empty(files[image].name, counts, spec)
        except DataError as e:
            if state.read == 1 and state.total > 1:  # the first image: its coordinates
                state.pending = e  # are checked with the next one first
                continue
            raise
        counts |= extra
        del f, ok
        s = np.full(len(X), k, dtype=np.int64)
        if spec.pitch:
            s, X, u, _ = bin_points(s, X, u, spec.pitch, spec.min_points)
            counts["bins"] = len(X)
            if len(X) == 0:
                raise DataError(
                    f"{files[image].name}: no bin of [binning] pitch = "
                    f"{spec.pitch:g} mm holds [binning] min_points = "
                    f"{spec.min_points} points ({counts['points']} points on the "
                    "specimen): lower min_points or enlarge the pitch"
                )
        report.append({"file": files[image].name, "image": image} | counts)
        steps.append(s)
        Xs.append(X)
        us.append(u)
    return np.concatenate(steps), np.vstack(Xs), np.vstack(us)


def _not_empty(name: str, counts: dict, spec: ImportSpec) -> None:
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


def _extent(name: str, X: np.ndarray, spec: ImportSpec) -> None:
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


def import_dic(spec: ImportSpec) -> tuple[Experiment, dict]:
    """The experiment (mm, N) of the exports ``spec`` describes, and the import report."""
    plugin = get_test(spec.setup.test)
    d = plugin.d
    steps_n = np.arange(1, len(spec.images) + 1)
    plugin.check_path(steps_n, spec.path, f"{spec.where}: [steps] path")
    files = image_files(spec)
    report: dict = {"files": [], "reference": []}
    state = _Reading()
    state.total = len(spec.images) + len(spec.reference_images)
    refs = None
    if spec.reference_images:
        refs = _collect(spec, files, spec.reference_images, d, True, report["reference"], state)
    step, X, u = _collect(spec, files, spec.images, d, refs is None, report["files"], state)
    for e, i in zip(report["files"], steps_n):
        e["step"] = int(i)
    level = noise(spec, refs, report["reference"], step, X, u)
    exp = Experiment(
        spec.name,
        spec.setup,
        steps_n,
        np.array(spec.path, float),
        None if spec.force is None else np.array(spec.force, float),
        step,
        X,
        u,
        noise_std=level["noise_std"],
        force_noise_std=spec.force_noise_std,
        source=spec.source
        | {"import": f"fabricsurf import-dic from {spec.layout.source}; see dic_import.json"},
    )
    checks.magnitudes(exp, "mm")
    report |= {
        "layout": spec.layout.name,
        "layout_source": spec.layout.source,
        "unit": spec.unit,
        "frame": {
            "mm_per_unit": spec.frame.scale,
            "y_down": spec.frame.y_down,
            "origin": list(spec.frame.origin),
            "grip": spec.frame.grip,
            "angle_deg": spec.frame.tilt_deg,
            "outside": spec.outside,
        },
        "binning": {"pitch_mm": spec.pitch, "min_points": spec.min_points},
        "coordinates": {
            "read_as": spec.layout.coordinates,
            "converted": spec.layout.coordinates == "deformed",
            "evidence": state.evidence,
        },
        "dropped_columns": state.dropped,
        "encoding": sorted({e["encoding"] for e in report["files"] + report["reference"]}),
        "noise": level,
        "rows_written": len(X),
        "points_read": int(sum(e["rows"] for e in report["files"])),
        "holes": int(sum(e["holes"] for e in report["files"])),
        "outside_dropped": int(sum(e["outside_dropped"] for e in report["files"])),
    }
    return exp, report
