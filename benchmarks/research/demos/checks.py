"""Moved to :mod:`fabricsurf.cli.demo`; this name stays only until demos/demo_woven_fabric.py
and demos/demo_forming.py import from there (then delete this file)."""

from fabricsurf.cli.demo import declared, entries, failures, verify

__all__ = ["declared", "entries", "failures", "verify"]
