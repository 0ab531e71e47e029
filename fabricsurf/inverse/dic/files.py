"""The export files of an import: [export] files as a glob, relative to dic.toml's directory
or absolute, and the image number of each file (``[export] image_number``)."""

from __future__ import annotations

import glob
from pathlib import Path
from typing import TYPE_CHECKING

from fabricsurf.errors import DataError

if TYPE_CHECKING:
    from fabricsurf.inverse.dic.description.spec import ImportSpec


def matching(root: Path, pattern: str) -> list[Path]:
    """The files matching ``pattern``: relative to ``root``, or absolute (glob.glob)."""
    if Path(pattern).is_absolute():
        return sorted(Path(p) for p in glob.glob(pattern))
    return sorted(root.glob(pattern))


def image_files(spec: ImportSpec) -> dict[int, Path]:
    """{image number: file} of the files matching the pattern; every file must be a listed
    step or reference image, and every listed image must have its file."""
    found: dict[int, Path] = {}
    for p in matching(spec.root, spec.files):
        if not p.is_file():
            continue
        m = spec.image_number.search(p.stem)
        if not m or not m.group(1).isdigit():
            raise DataError(
                f"{p.name}: no image number in the file name by [export] "
                f"image_number = {spec.image_number.pattern!r} (files matched by "
                f"[export] files = {spec.files!r})"
            )
        k = int(m.group(1))
        if k in found:
            raise DataError(
                f"{p.name} and {found[k].name} both give image {k} (by [export] "
                f"image_number = {spec.image_number.pattern!r}: set it to pick "
                'the image number, e.g. "first" or "-(\\d+)_")'
            )
        found[k] = p
    if not found:
        where = "" if Path(spec.files).is_absolute() else f" in {spec.root}"
        raise DataError(f"{spec.where}: [export] files = {spec.files!r} matches no file{where}")
    known = set(spec.images) | set(spec.reference_images)
    for k, p in sorted(found.items()):
        if k not in known:
            raise DataError(
                f"{p.name}: image {k} has no matching load step: it is in neither "
                f"[steps] images = {spec.images} nor reference_images = "
                f"{spec.reference_images} of {spec.where} (add it, or narrow "
                "[export] files)"
            )
    missing = [k for k in spec.images + spec.reference_images if k not in found]
    if missing:
        raise DataError(
            f"{spec.where}: image {missing[0]} of [steps] has no file among those "
            f"matching [export] files = {spec.files!r} (images found: "
            f"{sorted(found)[:10]}{' …' if len(found) > 10 else ''})"
        )
    return found
