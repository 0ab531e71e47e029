"""The field count of every data line of an export, counted on the file's bytes with numpy
(no Python loop over the lines), so that numpy's fast reader, which ignores fields beyond the
columns it is asked for, never reads a row with one field too many.

A line counts as data when it is not blank and does not start with ``#`` or ``*``; its
fields are its delimiters + 1 (or its runs of non-blank characters when the columns are
separated by blanks). The count is conservative: a line it cannot vouch for (a delimiter at
the end of the row, a comment after leading blanks) sends the file to the line-by-line
reader, which accepts or refuses each line exactly.
"""

from __future__ import annotations

import re

import numpy as np

from fabricsurf.inverse.dic.encoding import Encoding

_BLANKS = (32, 9, 13, 10)


def _units(raw: bytes, enc: Encoding) -> np.ndarray:
    """The file as an array of code units (bytes, or 16-bit units for UTF-16)."""
    if enc.unit == 1:
        return np.frombuffer(raw, np.uint8)[enc.bom :]
    body = raw[enc.bom :]
    body = body[: len(body) - len(body) % 2]
    return np.frombuffer(body, ">u2" if enc.big_endian else "<u2")


def fields_agree(
    raw: bytes, enc: Encoding, header_line: int, delimiter: str | None, width: int
) -> bool:
    """Whether every data line after the header (line ``header_line``, from 1) has exactly
    ``width`` fields. Memory: a boolean array of the file's size and the positions of its
    delimiters (one per field); the few lines of another count are looked at one by one."""
    buf = _units(raw, enc)
    ends = np.flatnonzero(buf == 10)
    starts = np.concatenate([[0], ends + 1])[header_line:]
    stops = np.concatenate([ends, [len(buf)]])[header_line:]
    keep = starts < len(buf)
    starts, stops = starts[keep], stops[keep]
    if len(starts) == 0:
        return True
    if delimiter is None:
        blank = np.isin(buf, _BLANKS)
        word = ~blank
        word[1:] &= blank[:-1]
        del blank
        marks, extra = np.flatnonzero(word), 0
        del word
    else:
        marks, extra = np.flatnonzero(buf == ord(delimiter)), 1
    fields = np.diff(np.searchsorted(marks, np.append(starts, len(buf)))) + extra
    del marks
    odd = np.flatnonzero(fields != width)
    if len(odd) > MAX_ODD_LINES:
        return False
    for k in odd:  # blank and comment lines are not data
        text = "".join(map(chr, buf[starts[k] : stops[k]].tolist())).strip()
        if text and not text.startswith(("#", "*")):
            return False
    return True


MAX_ODD_LINES = 1000
"""More lines than this of another field count (blank, comments or not) go to the
line-by-line reader without being looked at one by one."""
_INT = re.compile(r"[-+]?\d+")
_DIGITS = re.compile(r"\d+([eE][-+]?\d+)?")


def shifted_pair(cells: list[str], delimiter: str | None, extra: int) -> str:
    """A hint for a row with ``extra`` fields more than the header: the first pair of cells
    that reads like one number written with a decimal comma (``12,5`` split at the comma)."""
    if extra <= 0 or delimiter != ",":
        return ""
    for k in range(len(cells) - 1):
        a, b = cells[k].strip().strip('"'), cells[k + 1].strip().strip('"')
        if _INT.fullmatch(a) and _DIGITS.fullmatch(b):
            return (
                f"; fields {k + 1} and {k + 2} read '{a}' and '{b}': a decimal comma "
                f"({a},{b}) in a comma-separated file? Export with a decimal point, or "
                "with ';' between the columns"
            )
    return ""
