"""fabricsurf: woven fabric sheets as second-gradient elastic surfaces on FEniCSx.

The curated public API, layer by layer (docs/layout.md): the effect vocabulary (model), the
experiment plug-ins, and the measurement workflow (load, compare, fit, diagnose).
"""

__version__ = "0.2.0"

from fabricsurf.errors import DataError, InputError
from fabricsurf.experiments import TESTS, get_test
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.inverse.contract.data import Experiment, load_experiment, write_experiment
from fabricsurf.inverse.fitting.diagnose import diagnose
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.forward import ForwardModel, ForwardSet
from fabricsurf.model.terms import (
    EFFECTS,
    FibreStretch,
    GeodesicBending,
    NormalBending,
    Shear,
    ShearGradient,
    ShearLocking,
    StretchGradient,
    Twist,
    make_term,
    parse_terms,
)

__all__ = [
    "EFFECTS", "TESTS", "BiasExtension", "DataError", "Experiment", "FibreStretch",
    "ForwardModel", "ForwardSet", "GeodesicBending", "InputError", "NormalBending", "Shear",
    "ShearGradient", "ShearLocking", "StretchGradient", "Twist", "__version__", "diagnose",
    "fit", "get_test", "load_experiment", "make_term", "parse_terms", "write_experiment",
]
