"""A failing full-step attempt of the forming solver stops when it diverges
(fabricsurf/experiments/forming/contact_newton.py, ``FULL_STEP_DIVERGENCE``; docs/forming.md,
"A failing attempt stops early").

The shared hemisphere case formed to 8 mm in one requested step: its first full-step attempt
diverges. With the divergence tolerance it stops before its iteration limit (measured:
DIVERGED_DTOL at iteration 12 on 1 rank, 14 on 2: past the tenth iteration the diverging
iterates differ with the rounding); with the package's general tolerance (10⁸, the control) it
runs the whole limit. The repeat starts from the same predicted state either way, so the punch
force must agree to the Newton tolerance, with fewer Newton iterations in all.

Runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``.
"""

import pytest
from hemisphere_case import BLANK, PARAMS, TOOLING, H
from mpi4py import MPI
from petsc4py import PETSc

from fabricsurf.discretise.snes import SNES_DEFAULTS
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming.contact_newton import FULL_STEP_ITERATIONS
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist

COMM = MPI.COMM_WORLD
STROKE = 8.0
SAME = 1e-7
"""Relative agreement of the two forces: Newton's tolerance on the state (step_rtol 1e-8)
carried into the force, with room for different attempts after the first."""
Reason = PETSc.SNES.ConvergedReason


def _formed(snes_options: dict | None) -> tuple[float, list[tuple[int, int]], int]:
    """(punch force, (reason, iterations) of every attempt, Newton iterations of the step)."""
    model = [
        FibreStretch(**PARAMS["fibre_stretch"]),
        Shear(**PARAMS["shear"]),
        NormalBending(**PARAMS["normal_bending"]),
        Twist(**PARAMS["twist"]),
    ]
    setup = PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), dict(TOOLING))
    with HemispherePlugin(setup, model, H, COMM, snes_options=snes_options) as e:
        attempts = []
        attempt = e.solver._attempt

        def recorded(options):
            result = attempt(options)
            attempts.append(tuple(int(v) for v in result))
            return result

        e.solver._attempt = recorded
        e.set_load(0.0)
        e.run(STROKE, 1)
        return e.force[-1], attempts, sum(its for _, its in attempts)


@pytest.fixture(scope="module")
def runs():
    control = {"snes_divergence_tolerance": SNES_DEFAULTS["snes_divergence_tolerance"]}
    return _formed(None), _formed(control)


def test_a_diverging_attempt_stops_early(runs):
    (_, attempts, its), (_, attempts0, its0) = runs
    print(f"first attempt {attempts[0]} against {attempts0[0]}; {its} against {its0} iterations")
    assert attempts[0][0] == Reason.DIVERGED_DTOL
    assert attempts[0][1] < FULL_STEP_ITERATIONS
    assert attempts0[0] == (Reason.DIVERGED_MAX_IT, FULL_STEP_ITERATIONS)
    assert its < its0


def test_the_answer_does_not_depend_on_it(runs):
    (force, _, _), (force0, _, _) = runs
    assert abs(force - force0) < SAME * abs(force0)
