"""Moved to :mod:`fabricsurf.cli.demo`; this name stays only until demos/demo_woven_fabric.py
and demos/demo_forming.py import from there (then delete this file)."""

from fabricsurf.cli.demo import demo_parser, parse

__all__ = ["demo_parser", "parse"]
