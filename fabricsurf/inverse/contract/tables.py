"""Reading the files of a measurement directory: TOML and numeric CSV, with messages that name
the file, the line (header = line 1) or key, and the problem.

CSV dialects: comma-separated with a decimal point (the contract), and the semicolon-separated
exports of European spreadsheet and DIC software, whose decimal separator may be a comma; the
delimiter is read off the header line. A well-formed file (no quotes, no blank lines inside,
all cells numbers) is parsed by numpy's C reader in O(N) memory; anything else goes through the
row-by-row reader, which names the first bad row. UTF-8 with or without a byte-order mark, and
UTF-16 with its byte-order mark (spreadsheets' "Unicode text"); any other encoding is named with
the offending byte, its line, and what it would be in Windows-1252 (Latin-1); NUL bytes (UTF-16
without its byte-order mark, UTF-32) are refused. Blank lines (e.g. a trailing one) are
skipped. A FIFO, socket or device given as a file is refused as not a regular file.
"""

from __future__ import annotations

import codecs
import csv
import errno
import io
import math
import os
import re
import tomllib
from pathlib import Path

import numpy as np

from fabricsurf.errors import DataError


def broken_link(path: Path) -> str | None:
    """ "loops" or "dangles" when ``path`` is a symbolic link that loops or leads nowhere, else
    None."""
    if not path.is_symlink() or path.exists():
        return None
    try:
        os.stat(path)
    except OSError as e:
        return "loops" if e.errno == errno.ELOOP else "dangles"
    return None


def require_file(path: Path) -> None:
    """``path`` is a readable file; a symbolic link that loops or dangles is named as such."""
    if path.is_file():
        return
    name = path.name
    link = broken_link(path)
    if link == "loops":
        raise DataError(
            f"{name}: a symbolic link that loops ({name} -> "
            f"{os.readlink(path)}) in {path.parent}, not a file"
        )
    if link:
        raise DataError(
            f"{name}: a symbolic link to {os.readlink(path)}, which does not exist "
            f"(in {path.parent})"
        )
    if path.is_dir():
        raise DataError(f"{name}: a directory, not a file (in {path.parent})")
    kind = special_file(path)
    if kind:
        raise DataError(
            f"{name}: {kind}, not a regular file (in {path.parent}); give the data as a file"
        )
    raise DataError(f"{name}: file not found in {path.parent}")


def special_file(path: Path) -> str | None:
    """What ``path`` is when it exists but is neither a regular file nor a directory (a FIFO,
    socket or device: reading it could block or never end), else None."""
    if not path.exists() or path.is_file() or path.is_dir():
        return None
    return (
        "a named pipe (FIFO)"
        if path.is_fifo()
        else "a socket"
        if path.is_socket()
        else "a device"
        if path.is_char_device() or path.is_block_device()
        else "not a regular file"
    )


def read_toml(path: Path) -> dict:
    """The TOML file as a dict (a UTF-8 byte-order mark is accepted)."""
    name = path.name
    require_file(path)
    text = _decode(path)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise DataError(f"{name}: not valid TOML ({e})") from None


def _decode(path: Path) -> str:
    raw = path.read_bytes()
    utf16 = raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE))
    try:
        text = raw.decode("utf-16") if utf16 else raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        if utf16:
            raise DataError(
                f"{path.name}: not valid UTF-16 despite its byte-order mark "
                "(save the file as UTF-8)"
            ) from None
        line = raw[: e.start].count(b"\n") + 1
        byte = raw[e.start : e.start + 1]
        raise DataError(
            f"{path.name} line {line}: byte 0x{byte[0]:02x} is not UTF-8 ("
            f"{byte.decode('cp1252', errors='replace')!r} in Windows-1252/Latin-1?): "
            "save the file as UTF-8"
        ) from None
    if "\0" in text:  # valid UTF-8 (or UTF-16) with NUL characters: not text as given
        line = text[: text.index("\0")].count("\n") + 1
        guess = "UTF-16 without its byte-order mark?" if not utf16 else "UTF-32?"
        raise DataError(f"{path.name} line {line}: NUL bytes ({guess}): save the file as UTF-8")
    return text


def _number(cell: str, decimal_comma: bool) -> float:
    if decimal_comma:
        cell = cell.replace(",", ".")
    try:
        return float(cell)
    except ValueError:
        return math.nan


def _fast(text: str, columns: tuple[str, ...], optional: tuple[str, ...]) -> dict | None:
    """:func:`read_csv` of a well-formed file by ``np.loadtxt`` (module docstring), or None for
    any file it does not take: the row-by-row reader then reads it or names the error."""
    text = text.replace("\r\n", "\n").rstrip()
    head, _, body = text.partition("\n")
    if (
        not body
        or '"' in text
        or "\r" in text
        or not head.strip()
        or re.search(r"\n[ \t]*\n", text)
    ):
        return None
    delimiter = ";" if head.count(";") > head.count(",") else ","
    header = [h.strip() for h in head.split(delimiter)]
    wanted = list(columns) + [c for c in optional if c in header]
    if any(header.count(c) != 1 for c in wanted):
        return None
    if delimiter == ";":
        body = body.replace(",", ".")
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=delimiter, comments=None, ndmin=2)
    except ValueError:
        return None
    if data.shape[1] != len(header):
        return None
    out = {c: data[:, header.index(c)].copy() for c in wanted}
    if not all(np.isfinite(v).all() for v in out.values()):
        return None
    out["_line"] = np.arange(2, len(data) + 2)
    return out


def read_csv(path: Path, columns: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict:
    """Numeric columns of a CSV file as arrays, plus ``"_line"``: each row's line number."""
    name = path.name
    require_file(path)
    text = _decode(path)
    fast = _fast(text, columns, optional)
    if fast is not None:
        return fast
    lines = text.splitlines()
    numbered = [(i + 1, s) for i, s in enumerate(lines) if s.strip()]
    if not numbered:
        raise DataError(f"{name}: file is empty (expected header {','.join(columns)})")
    head = numbered[0][1]
    delimiter = ";" if head.count(";") > head.count(",") else ","
    if delimiter == "," and "\t" in head and "," not in head:
        raise DataError(
            f"{name} line 1: tab-separated header; expected comma- (or "
            f"semicolon-) separated columns {','.join(columns)}"
        )
    rows = list(csv.reader(io.StringIO("\n".join(s for _, s in numbered)), delimiter=delimiter))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in columns if c not in header]
    if missing:
        raise DataError(
            f"{name}: missing column(s) {', '.join(missing)}; header is {delimiter.join(header)}"
        )
    dup = [c for c in set(header) if header.count(c) > 1 and c in (*columns, *optional)]
    if dup:
        raise DataError(f"{name} line 1: column {dup[0]} appears twice")
    if len(rows) < 2:
        raise DataError(f"{name}: no data rows")
    wanted = list(columns) + [c for c in optional if c in header]
    out = {c: np.empty(len(rows) - 1) for c in wanted}
    out["_line"] = np.array([n for n, _ in numbered[1:]])
    comma = delimiter == ";"
    for i, row in enumerate(rows[1:]):
        line = numbered[i + 1][0]
        if len(row) != len(header):
            raise DataError(f"{name} line {line}: {len(row)} fields, header has {len(header)}")
        for c in wanted:
            cell = row[header.index(c)].strip()
            v = _number(cell, comma)
            if not math.isfinite(v):
                hint = (
                    " (a decimal comma: separate the columns with ';' or write the decimal "
                    "point '.')"
                    if not comma and re.fullmatch(r"[-+]?\d+,\d+", cell)
                    else ""
                )
                raise DataError(
                    f"{name} line {line}: column {c} = {cell!r} is not a finite number{hint}"
                )
            out[c][i] = v
    return out
