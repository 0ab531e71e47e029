"""Experiment plug-ins and their registry (the ``[loading] test`` values).

A new test is one module with an :class:`~fabricsurf.experiments.base.ExperimentSetup`
subclass and one entry in :data:`TESTS`.
"""

from __future__ import annotations

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import ExperimentSetup, Setup
from fabricsurf.experiments.bias_extension import BiasExtensionTest
from fabricsurf.experiments.cantilever import CantileverTest
from fabricsurf.experiments.hemisphere import HemisphereForming
from fabricsurf.experiments.picture_frame import PictureFrameTest

TESTS: dict[str, type[ExperimentSetup]] = {
    c.name: c for c in (BiasExtensionTest, PictureFrameTest, CantileverTest, HemisphereForming)
}
ALIASES = {"tensile": "bias_extension"}


def get_test(name: str) -> type[ExperimentSetup]:
    """The plug-in class of a test name (aliases accepted); unknown names list the valid ones."""
    key = ALIASES.get(name, name) if isinstance(name, str) else name
    if key not in TESTS:
        raise DataError(f"experiment.toml: [loading] test = {name!r} is not one of "
                        f"{sorted(TESTS) + sorted(ALIASES)}")
    return TESTS[key]


__all__ = ["ALIASES", "TESTS", "ExperimentSetup", "Setup", "get_test"]
