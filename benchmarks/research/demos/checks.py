"""The checks a demo declares on its summary.json, as plain data: one module-level ``CHECKS``
dict of the demo script, read here both by the demo itself (at its end) and by
tests/test_demos.py (from the source, with :func:`declared`, without running or importing the
demo, so without dolfinx).

A key is a path into the summary, segments separated by ``/``; the segment ``*`` stands for
every element of a list or every value of a dict. A value is

* ``...``: the entry exists;
* a tuple ``(low, high)``: a number with low ≤ value ≤ high (``None`` for an open end);
* anything else: equal to the entry (strings, integers, booleans, ``None``, lists).

Numbers only, no dolfinx: this module must import in a bare Python."""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any


def declared(script: Path) -> dict:
    """The ``CHECKS = {...}`` literal of a demo script, read from its source."""
    tree = ast.parse(Path(script).read_text(), filename=str(script))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "CHECKS" for t in node.targets):
            return ast.literal_eval(node.value)
    raise LookupError(f"{script}: no module-level CHECKS dict")


def entries(summary: Any, path: str) -> list[tuple[str, Any]]:
    """The (concrete path, value) pairs that ``path`` names in ``summary``."""
    found = [("", summary)]
    for seg in path.split("/"):
        nxt = []
        for where, node in found:
            if seg == "*":
                items = node.items() if isinstance(node, dict) else enumerate(node)
                nxt += [(f"{where}/{k}", v) for k, v in items]
            elif isinstance(node, dict) and seg in node:
                nxt.append((f"{where}/{seg}", node[seg]))
            else:
                raise KeyError(f"summary.json has no {where}/{seg} (check {path!r})")
        found = nxt
    return [(where.lstrip("/"), v) for where, v in found]


def failures(summary: dict, checks: dict) -> list[str]:
    """One line per declared check that ``summary`` does not meet (empty: all met)."""
    bad = []
    for path, want in checks.items():
        try:
            found = entries(summary, path)
        except (KeyError, TypeError) as e:
            bad.append(str(e))
            continue
        if not found:
            bad.append(f"{path}: matches nothing")
        for where, value in found:
            if want is ...:
                continue
            if isinstance(want, tuple):
                low, high = want
                ok = isinstance(value, (int, float)) and not isinstance(value, bool) and (
                    (low is None or value >= low) and (high is None or value <= high))
            else:
                ok = value == want
            if not ok:
                bad.append(f"{where} = {value!r}, declared {want!r}")
    return bad


def verify(summary: dict, checks: dict) -> None:
    """Raise AssertionError naming every declared check that ``summary`` does not meet."""
    bad = failures(summary, checks)
    assert not bad, "summary.json breaks its declared checks:\n  " + "\n  ".join(bad)
