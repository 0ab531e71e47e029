"""fabricsurf: woven fabric sheets as second-gradient elastic surfaces on FEniCSx.

The curated public API, layer by layer (docs/layout.md): the effect vocabulary (model), the
experiment plug-ins, and the measurement workflow (load, compare, fit, diagnose).

The names are imported on first use (PEP 562), so that ``import fabricsurf`` and
``import fabricsurf.network`` do not load dolfinx, petsc4py or ufl.
"""

from importlib import import_module

__version__ = "0.2.0"

_SOURCES = {
    "fabricsurf.errors": ("DataError", "InputError"),
    "fabricsurf.experiments": ("TESTS", "get_test"),
    "fabricsurf.experiments.bias_extension": ("BiasExtension",),
    "fabricsurf.inverse.contract.data": ("Experiment", "load_experiment", "write_experiment"),
    "fabricsurf.inverse.diagnosis.diagnose": ("diagnose",),
    "fabricsurf.inverse.fitting.compare": ("Comparison", "compare"),
    "fabricsurf.inverse.fitting.fit": ("fit",),
    "fabricsurf.inverse.forward.runs": ("ForwardModel", "ForwardSet"),
    "fabricsurf.model.terms": (
        "EFFECTS",
        "FibreStretch",
        "GeodesicBending",
        "NormalBending",
        "Shear",
        "ShearGradient",
        "ShearLocking",
        "StretchGradient",
        "Term",
        "Twist",
        "make_term",
        "parse_terms",
    ),
    "fabricsurf.model.user_effects": ("effects_from", "load_effects", "register_effect"),
}
_LAZY = {name: module for module, names in _SOURCES.items() for name in names}

__all__ = [
    "EFFECTS",
    "TESTS",
    "BiasExtension",
    "Comparison",
    "DataError",
    "Experiment",
    "FibreStretch",
    "ForwardModel",
    "ForwardSet",
    "GeodesicBending",
    "InputError",
    "NormalBending",
    "Shear",
    "ShearGradient",
    "ShearLocking",
    "StretchGradient",
    "Term",
    "Twist",
    "__version__",
    "compare",
    "diagnose",
    "effects_from",
    "fit",
    "get_test",
    "load_effects",
    "load_experiment",
    "make_term",
    "parse_terms",
    "register_effect",
    "write_experiment",
]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value  # imported once
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
