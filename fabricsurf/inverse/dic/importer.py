"""DIC exports → an :class:`~fabricsurf.inverse.contract.experiment.Experiment` (docs/dic.md).

One file per image; the image number is an integer of the file's name (the last by default,
``[export] image_number``). Each image is read, its holes (NaN or empty cells, the layout's
lost-point flags) dropped and counted, its coordinates checked against the first image read
(reference or deformed, :mod:`~fabricsurf.inverse.dic.coordinates`) and made reference ones, its
points moved to the specimen's frame, checked (duplicates, outline:
:mod:`~fabricsurf.inverse.dic.image_points`) and, with a pitch, binned before the next is read:
the memory is that of one image, the first image's points and the binned result.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.errors import DataError
from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract import checks
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.dic import coordinates
from fabricsurf.inverse.dic.binning import bin_points
from fabricsurf.inverse.dic.description.spec import ImportSpec
from fabricsurf.inverse.dic.files import image_files
from fabricsurf.inverse.dic.image_points import (
    check_extent,
    check_not_empty,
    check_units,
    points_of_image,
    valid_rows,
)
from fabricsurf.inverse.dic.noise import noise
from fabricsurf.inverse.dic.reader import ExportFile, read_export


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
    check_units(f, spec.unit)
    ok = valid_rows(f, spec, d)
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
            X, u, counts = points_of_image(f, spec, d, tilt_first and k == 1, ok)
            if k == 1 and len(X):
                check_extent(files[image].name, X, spec)
            check_not_empty(files[image].name, counts, spec)
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
