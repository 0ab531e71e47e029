"""Load stepping: steps are cut on divergence and regrown, and a clear error names the step,
the last converged load and the SNES reason once the minimum step is reached."""

import numpy as np
import pytest

from fabricsurf.discretise.solver import LoadStepError, LoadStepper


class StubSolver:
    """Converges only for load increments up to ``max_inc`` (like Newton's basin)."""

    def __init__(self, max_inc):
        self.max_inc, self.t, self.t_try = max_inc, 0.0, 0.0

        class U:
            def __init__(self):
                self.x = type("X", (), {"array": np.zeros(1), "scatter_forward": lambda s: None})()
                self.vector = self

            def copy(self, other=None):
                return self

        self.u = U()

    def set(self, t):
        self.t_try = t

    def solve(self):
        if abs(self.t_try - self.t) <= self.max_inc:
            self.t = self.t_try
            return 2, 3
        return -5, 25


def test_cut_and_regrow():
    s = StubSolver(max_inc=0.3)
    done = []
    stepper = LoadStepper(s, s.set, lambda k, t, its: done.append(t))
    stepper.run([1.0, 2.0])
    assert done == [1.0, 2.0] and s.t == 2.0


def test_minimum_step_error_names_step_and_last_load():
    s = StubSolver(max_inc=1e-6)
    done = []
    stepper = LoadStepper(s, s.set, lambda k, t, its: done.append(t), min_fraction=1e-3)
    with pytest.raises(LoadStepError, match=r"load step 0 \(target 1\).*last converged load 0"
                                            r".*SNES converged reason -5"):
        stepper.run([1.0])
    assert done == []
