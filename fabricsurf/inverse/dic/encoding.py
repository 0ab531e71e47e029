"""The text encoding of an export file, declared (``[export] encoding``) or detected, never
guessed between two encodings that would give different text.

Detection: a byte-order mark names UTF-8 or UTF-16 (LE/BE); a file that is valid UTF-8 is
UTF-8 (Latin-1 text passes as UTF-8 only when its accented letters happen to form UTF-8
sequences, "Ã©"-like pairs no export header holds; the key overrides it); otherwise it is one of
the single-byte Western encodings. Latin-1 and cp1252 read every byte alike except
0x80–0x9F (cp1252: € ‚ … ² is not among them, but ‰ Œ ‘ ’ “ ” – — ™ are; Latin-1: control
characters): a file without such bytes is read as "latin-1/cp1252 (same text)", one with them
is refused, naming the byte, its line and both readings, until the key says which.
"""

from __future__ import annotations

import codecs
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fabricsurf.errors import DataError

ENCODINGS = {
    "utf-8": "utf-8-sig",
    "utf-16": "utf-16",
    "utf-16-le": "utf-16-le",
    "utf-16-be": "utf-16-be",
    "latin-1": "latin-1",
    "cp1252": "cp1252",
}
"""[export] encoding values → the Python codec that reads them (utf-8 with or without BOM;
utf-16 with a BOM; utf-16-le/-be without one)."""


@dataclass(frozen=True)
class Encoding:
    """``codec``: what the file is opened with; ``label``: what dic_import.json records;
    ``unit``: bytes per code unit (2 for UTF-16, whose field counting reads 16-bit units);
    ``bom``: bytes to skip before the text."""

    codec: str
    label: str
    unit: int = 1
    bom: int = 0
    big_endian: bool = False


def normalise(value, where: str) -> str | None:
    """The checked [export] encoding key (None when absent)."""
    if value is None:
        return None
    key = str(value).strip().lower().replace("_", "-")
    key = {
        "utf8": "utf-8",
        "latin1": "latin-1",
        "iso-8859-1": "latin-1",
        "windows-1252": "cp1252",
        "utf16": "utf-16",
    }.get(key, key)
    if not isinstance(value, str) or key not in ENCODINGS:
        raise DataError(f"{where}: [export] encoding = {value!r} is not one of {sorted(ENCODINGS)}")
    return key


def _line_of(buf: np.ndarray, pos: int) -> int:
    return int(np.count_nonzero(buf[:pos] == 10)) + 1


def _declared(path: Path, raw: bytes, key: str) -> Encoding:
    if key.startswith("utf-16"):
        bom = raw[:2] in (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)
        if key == "utf-16" and not bom:
            raise DataError(
                f'{path.name}: [export] encoding = "utf-16" but the file has no '
                'byte-order mark: set "utf-16-le" or "utf-16-be"'
            )
        big = raw[:2] == codecs.BOM_UTF16_BE if key == "utf-16" else key.endswith("be")
        codec = "utf-16" if bom else ENCODINGS[key]  # "utf-16" reads and drops the BOM
        enc = Encoding(codec, key, 2, 2 if bom else 0, big)
    else:
        enc = Encoding(ENCODINGS[key], key, 1, 3 if raw[:3] == codecs.BOM_UTF8 else 0)
    try:
        raw.decode(enc.codec)
    except UnicodeDecodeError as e:
        buf = np.frombuffer(raw, np.uint8)
        raise DataError(
            f"{path.name} line {_line_of(buf, e.start)}: byte 0x{raw[e.start]:02X} "
            f"at offset {e.start} cannot be read as {key} ({e.reason}), the "
            "[export] encoding given; check the key (utf-8, utf-16, latin-1, "
            "cp1252)"
        ) from None
    return enc


def detect(path: Path, raw: bytes, key: str | None) -> Encoding:
    """The encoding of ``path`` (its bytes ``raw``): the declared ``key``, or detected
    (module docstring)."""
    if key is not None:
        return _declared(path, raw, key)
    if raw[:2] in (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE):
        big = raw[:2] == codecs.BOM_UTF16_BE
        enc = _declared(path, raw, "utf-16")
        return Encoding(enc.codec, f"utf-16-{'be' if big else 'le'} (with BOM)", 2, 2, big)
    if raw[:3] == codecs.BOM_UTF8:
        return Encoding("utf-8-sig", "utf-8 (with BOM)", 1, 3)
    try:
        raw.decode("utf-8")
        return Encoding("utf-8-sig", "utf-8")
    except UnicodeDecodeError as e:
        first_bad = e.start
    buf = np.frombuffer(raw, np.uint8)
    if len(raw) > 1 and np.count_nonzero(buf[: min(len(buf), 4096)] == 0) > 0:
        raise DataError(
            f"{path.name}: NUL bytes and no byte-order mark: UTF-16 without a BOM? "
            'set [export] encoding = "utf-16-le" (Windows) or "utf-16-be"'
        )
    ambiguous = np.flatnonzero((buf >= 0x80) & (buf <= 0x9F))
    if len(ambiguous):
        pos = int(ambiguous[0])
        b = raw[pos : pos + 1]
        try:
            windows = repr(b.decode("cp1252"))
        except UnicodeDecodeError:
            windows = "undefined"
        raise DataError(
            f"{path.name} line {_line_of(buf, pos)}: not UTF-8 (byte "
            f"0x{raw[first_bad]:02X} at offset {first_bad}), and byte 0x{b[0]:02X} "
            f"reads as {windows} in cp1252 but as the control character "
            f'U+00{b[0]:02X} in latin-1: set [export] encoding = "cp1252" '
            '(Windows exports) or "latin-1"'
        )
    return Encoding("latin-1", "latin-1/cp1252 (same text)")
