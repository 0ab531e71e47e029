"""A forward model of a few moduli with closed-form residuals, for the fit's own logic
(fabricsurf/inverse/fitting/fit.py) without a mesh: a subclass gives ``residuals(pred)`` (the
residuals and their Jacobian in the moduli); a run returns the moduli and counts itself."""

from types import SimpleNamespace

import numpy as np
from mpi4py import MPI


class ToyForward:
    """Moduli ``names`` ("term.param") at ``values``; ``scout``: the model :meth:`coarse` gives
    (the scale scan's scout mesh), if any."""

    noise_known = True
    experiments: list = []

    def __init__(self, names: list[str], values, comm=MPI.COMM_WORLD, scout=None) -> None:
        self.names, self.comm, self.scout, self.forward_runs = names, comm, scout, 0
        self.params = [(SimpleNamespace(name=n.split(".")[0]), n.split(".")[1]) for n in names]
        self.v = np.array(values, float)

    def coarse(self, factor):
        return self.scout

    def values(self):
        return self.v.copy()

    def set_values(self, v):
        self.v = np.array(v, float)

    def run(self, sens=False):
        self.forward_runs += 1
        return self.v.copy()

    def misfit(self, pred):
        return {}
