"""Reading one DIC export file (one image) into arrays, in O(N) memory.

The header is the last non-blank line before the first data line (a line of numbers); lines
before it are the export's metadata (``***`` in DICe, ``#`` in the ARAMIS nodemap, whose
header line itself starts with ``#``). The delimiter is read off the header: ``;``, ``,``, a
tab, or blanks. The numbers are parsed by numpy's C reader, after a vectorised count of
the fields of every data line (numpy's reader, given the columns to use, ignores extra fields:
a decimal comma in a comma-separated file would shift the values silently). A file with a line
of another field count, or one the C reader cannot read (an empty cell, a decimal comma, a
stray word), is read again line by line, so that an empty cell or NaN becomes a hole and
anything else an error naming the file, line, column and value. The text encoding is declared
or detected (:mod:`~fabricsurf.inverse.dic.encoding`).
"""

from __future__ import annotations

import math
import re
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fabricsurf.errors import DataError
from fabricsurf.inverse.contract.tables import require_file
from fabricsurf.inverse.dic.encoding import Encoding, detect
from fabricsurf.inverse.dic.fields import fields_agree, shifted_pair
from fabricsurf.inverse.dic.layouts import OPTIONAL, Layout, guess_layout, split_unit

MAX_PREAMBLE = 2000
"""Lines searched for the header and the first data line."""
COMMENT = ("#", "*")
ROLE_KEY = {"px": "pixel_x", "py": "pixel_y"}
NAN_WORDS = {"", "nan", "-nan", "+nan", "na", "n/a", "1.#qnan", "-1.#ind", "null", "none"}


@dataclass
class ExportFile:
    """One image of an export: ``data`` holds each role's column (NaN where a cell was empty
    or NaN); ``units`` the unit tag of each role's header cell (None when untagged)."""

    path: Path
    image: int
    data: dict[str, np.ndarray]
    units: dict[str, str | None]
    header_line: int
    encoding: Encoding = field(default_factory=lambda: Encoding("utf-8-sig", "utf-8"))
    names: dict[str, str] = field(default_factory=dict)
    """{role: the header name it was read from}."""
    _lines: np.ndarray | None = field(default=None, repr=False)

    @property
    def n(self) -> int:
        return len(self.data["x"])

    def line_of(self, row: int) -> int:
        """The file's line number (from 1) of data row ``row`` (scanned once, when asked)."""
        if self._lines is None:
            self._lines = np.array(
                list(_data_lines(self.path, self.header_line, self.encoding.codec))
            )
        return int(self._lines[row])


def _is_number(cell: str) -> bool:
    c = cell.strip().strip('"')
    if c.lower() in NAN_WORDS:
        return True
    try:
        float(c.replace(",", "."))
    except ValueError:
        return False
    return True


def _split(line: str, delimiter: str | None) -> list[str]:
    return line.split(delimiter) if delimiter else line.split()


def _delimiter(header: str) -> str | None:
    counts = {d: header.count(d) for d in (";", ",", "\t")}
    best = max(counts, key=counts.get)
    return best if counts[best] else None


def _is_data(line: str) -> bool:
    s = line.strip()
    if not s or s.startswith(COMMENT):
        return False
    cells = _split(s, _delimiter(s))
    return len(cells) >= 2 and all(_is_number(c) for c in cells)


def _header_text(line: str) -> str:
    """The header's names: without a comment mark, and without DaVis's ``#DaVis 10.x 2C
    vector field 4 545 740`` prefix before its quoted names."""
    text = line.strip().lstrip("#*").strip()
    if text.startswith("DaVis") and '"' in text:
        text = text[text.index('"') :]
    return text


def find_header(path: Path, codec: str = "utf-8-sig") -> tuple[int, list[str], str | None]:
    """(header line number from 1, header cells, delimiter) of an export file."""
    previous = None
    try:
        with open(path, encoding=codec) as fh:
            for number, line in enumerate(fh, start=1):
                if number > MAX_PREAMBLE:
                    break
                if _is_data(line):
                    if previous is None:
                        raise DataError(
                            f"{path.name} line {number}: data before any header "
                            "line (the column names)"
                        )
                    text = _header_text(previous[1])
                    d = _delimiter(text)
                    return previous[0], [c.strip() for c in _split(text, d)], d
                if line.strip():
                    previous = (number, line)
    except UnicodeDecodeError as e:  # detect() read the whole file: not expected here
        raise DataError(
            f"{path.name}: not {codec} text ({e.reason} at byte {e.start}); set [export] encoding"
        ) from None
    raise DataError(
        f"{path.name}: no data line (a line of numbers) in its first {MAX_PREAMBLE} lines"
    )


def _data_lines(path: Path, header_line: int, codec: str):
    """Line numbers of the data lines after the header (blank and comment lines skipped)."""
    with open(path, encoding=codec) as fh:
        for number, line in enumerate(fh, start=1):
            s = line.strip()
            if number > header_line and s and not s.startswith(COMMENT):
                yield number


def _roles(
    path: Path, cells: list[str], layout: Layout, header_line: int
) -> tuple[dict[str, int], dict[str, str | None], dict[str, str]]:
    names = [split_unit(c) for c in cells]
    index, units = {}, {}
    tags = dict(layout.tags)
    for role, accepted in layout.columns().items():
        name = next((a for a in accepted if any(n == a for n, _ in names)), accepted[0])
        hits = [i for i, (n, _) in enumerate(names) if n == name]
        if len(hits) > 1:
            raise DataError(f"{path.name} line {header_line}: column {name!r} appears twice")
        if not hits:
            if role in OPTIONAL or role.startswith("flag"):
                continue
            other = guess_layout({n for n, _ in names})
            hint = f' (it looks like layout = "{other}")' if other else ""
            raise DataError(
                f"{path.name} line {header_line}: no column {name!r} (the "
                f"{layout.name} layout's {role}); the header has "
                f"{', '.join(n for n, _ in names)}{hint}"
            )
        unit = names[hits[0]][1]
        if role in tags:
            given = tags[role]
            if unit is not None and unit.lower() != given.lower():
                raise DataError(
                    f"{path.name} line {header_line}: column {name!r} is in "
                    f"[{unit}] but [columns] {ROLE_KEY.get(role, role)} = "
                    f'"{name} [{given}]" says [{given}]: correct the unit in '
                    "[columns] or the export"
                )
            unit = unit or given
        index[role], units[role] = hits[0], unit
    return index, units, {r: names[i][0] for r, i in index.items()}


def read_export(path: Path, image: int, layout: Layout, encoding: str | None = None) -> ExportFile:
    """Read one export file: the layout's columns as float arrays (NaN for holes).
    ``encoding``: the [export] encoding key, or None to detect it."""
    require_file(path)
    raw = path.read_bytes()
    enc = detect(path, raw, encoding)
    header_line, cells, delim = find_header(path, enc.codec)
    index, units, found = _roles(path, cells, layout, header_line)
    roles = list(index)
    data = None
    if fields_agree(raw, enc, header_line, delim, len(cells)):
        del raw
        try:
            table = np.loadtxt(
                path,
                delimiter=delim,
                skiprows=header_line,
                comments=COMMENT,
                usecols=[index[r] for r in roles],
                ndmin=2,
                encoding=enc.codec,
            )
            data = {r: np.ascontiguousarray(table[:, k]) for k, r in enumerate(roles)}
            del table
        except ValueError:
            pass
    else:
        del raw
    if data is None:
        data = _slow_read(path, header_line, delim, index, len(cells), enc.codec)
    if len(data["x"]) == 0:
        raise DataError(f"{path.name}: no data rows after the header (line {header_line})")
    return ExportFile(path, image, data, units, header_line, enc, found)


def _cell_value(cell: str, comma: bool, where: str) -> float:
    c = cell.strip().strip('"')
    if c.lower() in NAN_WORDS:
        return math.nan
    try:
        return float(c.replace(",", ".") if comma else c)
    except ValueError:
        hint = (
            " (a decimal comma in a comma-separated file: separate the columns with ';')"
            if not comma and re.fullmatch(r"[-+]?\d+,\d+", c)
            else ""
        )
        raise DataError(f"{where} = {cell.strip()!r} is not a number{hint}") from None


def _slow_read(
    path: Path, header_line: int, delim: str | None, index: dict[str, int], width: int, codec: str
) -> dict[str, np.ndarray]:
    """Line-by-line reading: empty and NaN cells are holes, other text an error."""
    comma = delim in (";", "\t", None)
    out = {r: array("d") for r in index}
    with open(path, encoding=codec) as fh:
        for number, line in enumerate(fh, start=1):
            s = line.strip()
            if number <= header_line or not s or s.startswith(COMMENT):
                continue
            cells = _split(line.rstrip("\r\n"), delim)
            while len(cells) > width and not cells[-1].strip():
                cells.pop()  # a delimiter at the end of the row
            if len(cells) != width:
                raise DataError(
                    f"{path.name} line {number}: {len(cells)} fields, the header "
                    f"(line {header_line}) has {width}"
                    + shifted_pair(cells, delim, len(cells) - width)
                )
            for role, k in index.items():
                out[role].append(
                    _cell_value(cells[k], comma, f"{path.name} line {number}: column {k + 1}")
                )
    return {r: np.frombuffer(v, dtype=float).copy() for r, v in out.items()}
