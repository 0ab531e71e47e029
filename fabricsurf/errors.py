"""Errors that name what the user gave wrong (the lowest layer: any layer may raise them)."""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input; the message names the file, row or key, and the problem."""


class DataError(InputError):
    """Bad measurement input (docs/contracts.md); the message names file, row or key, and the
    problem."""
