"""Reading one DIC export file (one image) into arrays, in O(N) memory.

The header is the last non-blank line before the first data line (a line of numbers); lines
before it are the export's metadata (``***`` in DICe, ``#`` in the ARAMIS nodemap, whose
header line itself starts with ``#``). The delimiter is read off the header: ``;``, ``,``, a
tab, or blanks. The numbers are parsed by numpy's C reader; a file it cannot read (an empty
cell, a decimal comma, a stray word) is read again line by line, so that an empty cell or NaN
becomes a hole and anything else an error naming the file, line, column and value.
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
from fabricsurf.inverse.dic.layouts import Layout, split_unit

MAX_PREAMBLE = 2000
"""Lines searched for the header and the first data line."""
COMMENT = ("#", "*")
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
    _lines: np.ndarray | None = field(default=None, repr=False)

    @property
    def n(self) -> int:
        return len(self.data["x"])

    def line_of(self, row: int) -> int:
        """The file's line number (from 1) of data row ``row`` (scanned once, when asked)."""
        if self._lines is None:
            self._lines = np.array(list(_data_lines(self.path, self.header_line)))
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


def find_header(path: Path) -> tuple[int, list[str], str | None]:
    """(header line number from 1, header cells, delimiter) of an export file."""
    previous = None
    try:
        with open(path, encoding="utf-8-sig") as fh:
            for number, line in enumerate(fh, start=1):
                if number > MAX_PREAMBLE:
                    break
                if _is_data(line):
                    if previous is None:
                        raise DataError(f"{path.name} line {number}: data before any header "
                                        "line (the column names)")
                    text = previous[1].strip().lstrip("#*").strip()
                    d = _delimiter(text)
                    return previous[0], [c.strip() for c in _split(text, d)], d
                if line.strip():
                    previous = (number, line)
    except UnicodeDecodeError as e:
        raise DataError(f"{path.name}: not UTF-8 text ({e.reason} at byte {e.start}); "
                        "export the file as UTF-8 or ASCII") from None
    raise DataError(f"{path.name}: no data line (a line of numbers) in its first "
                    f"{MAX_PREAMBLE} lines")


def _data_lines(path: Path, header_line: int):
    """Line numbers of the data lines after the header (blank and comment lines skipped)."""
    with open(path, encoding="utf-8-sig") as fh:
        for number, line in enumerate(fh, start=1):
            s = line.strip()
            if number > header_line and s and not s.startswith(COMMENT):
                yield number


def _roles(path: Path, cells: list[str], layout: Layout, header_line: int
           ) -> tuple[dict[str, int], dict[str, str | None]]:
    names = [split_unit(c) for c in cells]
    index, units = {}, {}
    for role, name in layout.columns().items():
        hits = [i for i, (n, _) in enumerate(names) if n == name]
        if len(hits) > 1:
            raise DataError(f"{path.name} line {header_line}: column {name!r} appears twice")
        if not hits:
            if role in ("z", "w", "valid"):
                continue
            raise DataError(f"{path.name} line {header_line}: no column {name!r} (the "
                            f"{layout.name} layout's {role}); the header has "
                            f"{', '.join(n for n, _ in names)}")
        index[role], units[role] = hits[0], names[hits[0]][1]
    return index, units


def read_export(path: Path, image: int, layout: Layout) -> ExportFile:
    """Read one export file: the layout's columns as float arrays (NaN for holes)."""
    require_file(path)
    header_line, cells, delim = find_header(path)
    index, units = _roles(path, cells, layout, header_line)
    roles = list(index)
    try:
        table = np.loadtxt(path, delimiter=delim, skiprows=header_line, comments=COMMENT,
                           usecols=[index[r] for r in roles], ndmin=2, encoding="utf-8-sig")
        data = {r: np.ascontiguousarray(table[:, k]) for k, r in enumerate(roles)}
        del table
    except ValueError:
        data = _slow_read(path, header_line, delim, index, len(cells))
    if len(data["x"]) == 0:
        raise DataError(f"{path.name}: no data rows after the header (line {header_line})")
    return ExportFile(path, image, data, units, header_line)


def _cell_value(cell: str, comma: bool, where: str) -> float:
    c = cell.strip().strip('"')
    if c.lower() in NAN_WORDS:
        return math.nan
    try:
        return float(c.replace(",", ".") if comma else c)
    except ValueError:
        hint = (" (a decimal comma in a comma-separated file: separate the columns with ';')"
                if not comma and re.fullmatch(r"[-+]?\d+,\d+", c) else "")
        raise DataError(f"{where} = {cell.strip()!r} is not a number{hint}") from None


def _slow_read(path: Path, header_line: int, delim: str | None, index: dict[str, int],
               width: int) -> dict[str, np.ndarray]:
    """Line-by-line reading: empty and NaN cells are holes, other text an error."""
    comma = delim in (";", "\t", None)
    out = {r: array("d") for r in index}
    with open(path, encoding="utf-8-sig") as fh:
        for number, line in enumerate(fh, start=1):
            s = line.strip()
            if number <= header_line or not s or s.startswith(COMMENT):
                continue
            cells = _split(line.rstrip("\r\n"), delim)
            while len(cells) > width and not cells[-1].strip():
                cells.pop()  # a delimiter at the end of the row
            if len(cells) != width:
                raise DataError(f"{path.name} line {number}: {len(cells)} fields, the header "
                                f"(line {header_line}) has {width}")
            for role, k in index.items():
                out[role].append(_cell_value(cells[k], comma,
                                             f"{path.name} line {number}: column {k + 1}"))
    return {r: np.frombuffer(v, dtype=float).copy() for r, v in out.items()}
