"""A cut stroke increment is continuation, not a step of the friction's path
(fabricsurf/discretise/stepping.py, fabricsurf/experiments/forming/contact_newton.py;
docs/forming.md, "Cuts that do not change the path").

With friction the state at a stroke depends on the steps taken to it: the friction of each
step is written from the state the step started from. When Newton failed and the load stepper
cut an increment, the cut became a step of the path, and the answer jumped wherever a nearby
set of moduli needed one cut more or less: by 7.1 times the force noise at one stroke of the
forming diagnosis's ``locking`` case (benchmarks/forming_diagnosis.py), a jump no sensitivity
sees.
Now the cut loads only give Newton its start:

* the stepper tells the solver which attempt is at the requested load
  (tests/test_load_stepping.py, ``test_stepper_says_which_attempt_ends_the_step``);
* the hemisphere with friction under the holder, formed to two strokes with every increment cut
  once, gives the punch force and the dissipation of the uncut run to the Newton tolerance;
  the control, the cut solves taken as steps of the path (as before), differs by more than
  1e-3 (measured: the cut runs agree to 2e-12; the old cuts differ by 1.5 % in the force and
  1.0 % in the dissipation, on 1 and 2 ranks).

Runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``.
"""

import pytest
from hemisphere_case import BLANK, FRICTION, TOOLING, H
from mpi4py import MPI

from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist

COMM = MPI.COMM_WORLD
STROKES = (3.0, 6.0)
SAME = 1e-7
"""Relative agreement of cut and uncut runs: Newton's tolerance on the state (step_rtol 1e-8)
carried into the force, with room for the different starts."""
CONTROL = 1e-3
"""Smallest difference the old cuts must show for the check to mean anything."""


def _formed(e: HemispherePlugin, loads: list[float], ends: list[bool]) -> tuple[float, float]:
    """(punch force, dissipation) after solving ``loads`` in turn from the flat blank, each
    attempt told whether it ends a requested step."""
    e.solver.reset()
    e.set_load(0.0)
    for s, end in zip(loads, ends):
        e.set_load(s)
        e.solver.step_end = end
        reason, _ = e.solver.solve()
        assert reason > 0, f"no convergence at stroke {s}"
    return e.reaction(), e.dissipated()


@pytest.fixture(scope="module")
def runs():
    model = [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=0.01), NormalBending(k_b=1e-3)]
    model.append(Twist(k_t=1e-3))
    opts = dict(TOOLING, **FRICTION)
    cut = [0.5 * STROKES[0], STROKES[0], 0.5 * sum(STROKES), STROKES[1]]
    with HemispherePlugin(
        PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model, H, COMM
    ) as e:
        return {
            "uncut": _formed(e, list(STROKES), [True, True]),
            "cut": _formed(e, cut, [False, True, False, True]),
            "old cuts": _formed(e, cut, [True] * 4),
        }


def test_cut_increments_leave_the_path_unchanged(runs):
    (F0, D0), (F1, D1), (F2, D2) = runs["uncut"], runs["cut"], runs["old cuts"]
    print(
        f"force {F0:.10g} N: cut {F1 / F0 - 1:.2e}, old cuts {F2 / F0 - 1:.2e} relative; "
        f"dissipation {D0:.8g} N·mm: cut {D1 / D0 - 1:.2e}, old cuts {D2 / D0 - 1:.2e}"
    )
    assert abs(F1 - F0) < SAME * abs(F0)
    assert abs(D1 - D0) < SAME * abs(D0)
    assert abs(F2 - F0) > CONTROL * abs(F0) or abs(D2 - D0) > CONTROL * abs(D0)
