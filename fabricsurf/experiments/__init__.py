"""Experiment plug-ins and their registry (the ``[loading] test`` values).

A new test is one module with an :class:`~fabricsurf.experiments.base.ExperimentPlugin`
subclass and one entry in :data:`TESTS`.
"""

from __future__ import annotations

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import ExperimentPlugin, PluginSetup
from fabricsurf.experiments.bias_plugin import BiasExtensionPlugin
from fabricsurf.experiments.cantilever import CantileverPlugin
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.experiments.picture_frame import PictureFramePlugin

TESTS: dict[str, type[ExperimentPlugin]] = {
    c.name: c for c in (BiasExtensionPlugin, PictureFramePlugin, CantileverPlugin, HemispherePlugin)
}
ALIASES: dict[str, str] = {}
"""Other names of a test (none now: ``tensile`` was one of ``bias_extension``, see
:data:`NOT_MODELLED`)."""

NOT_MODELLED = {
    "tensile": "a tensile test (the yarns pulled along the load, fibres at 0/90 deg) is not "
    "modelled: the bias-extension geometry degenerates there (fibres run from clamp "
    "to grip), so no plug-in takes it; for a bias-extension test (fibres on the bias, "
    'e.g. fibre_angles_deg = [45.0, -45.0]) write test = "bias_extension"; a fibre '
    "stiffness measured in a tensile test can be held with diagnose --fixed "
    "fibre_stretch",
}
"""Test names that are refused with what they mean and what to do (``tensile`` was once an
alias of ``bias_extension``: a name promising a test that plug-in refuses)."""


def get_test(name: str) -> type[ExperimentPlugin]:
    """The plug-in class of a test name (aliases accepted); unknown names list the valid ones,
    a name of :data:`NOT_MODELLED` says why it is not a test here."""
    key = ALIASES.get(name, name) if isinstance(name, str) else name
    if isinstance(key, str) and key in NOT_MODELLED:
        raise DataError(f"experiment.toml: [loading] test = {name!r}: {NOT_MODELLED[key]}")
    if key not in TESTS:
        raise DataError(
            f"experiment.toml: [loading] test = {name!r} is not one of "
            f"{sorted(TESTS) + sorted(ALIASES)}"
        )
    return TESTS[key]


__all__ = ["ALIASES", "NOT_MODELLED", "TESTS", "ExperimentPlugin", "PluginSetup", "get_test"]
