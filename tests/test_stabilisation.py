"""The forming run's viscous stabilisation (``[tooling] stabilisation`` η: a drag η dr/ds on the
sheet's motion per unit stroke, the step's potential ½ (η/Δs)|r − r_n|²;
experiments/forming/friction.py, docs/tool_surfaces.md, "Through a snap").

Checks that can fail independently of each other, on the tests' hemisphere set-up (a 60 mm
blank at ±45° over a 20 mm punch, 4 mm of stroke, frictionless):

* the work balance ∫ F ds = ΔΠ + D_v closes with the drag's dissipation D_v summed by the
  trapezoid rule, its error falling at rate 2 with the step (measured 0.0542, 0.0144, 0.0038
  N·mm in 4, 8 and 16 steps at η = 2·10⁻⁴ N/mm², where D_v is about 0.3 N·mm, a fifth of the
  work: leaving it out, or summing it with the end-of-step traction alone, fails the rate);
* D_v does not depend on the step count in the limit (the drag is η/Δs, a rate per unit
  stroke): it converges at first order, the backward step's, differences 0.026, 0.013 N·mm;
* the answer tends to the undamped one linearly in η: the force's difference doubles with η;
* an η outside [0, 1] N/mm² is refused naming the key; a share of the work above
  STABILISATION_SHARE is a warning.
"""

import logging
import math
from itertools import pairwise

import numpy as np
import pytest
from hemisphere_case import BLANK, TOOLING, H
from mpi4py import MPI

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming.stroke_log import STABILISATION_SHARE, stabilisation_share
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist

COMM = MPI.COMM_WORLD
STROKE, ETA = 4.0, 2e-4


def model():
    return [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]


def formed(eta: float, steps: int) -> dict:
    """Balance error, work, the drag's dissipation and the final force of one run."""
    opts = {**TOOLING, "stabilisation": eta}
    setup = PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts)
    with HemispherePlugin(setup, model(), H, COMM) as e:
        start = sum(e.energies())
        e.run(STROKE, steps)
        work = float(np.trapz(e.force, e.stroke))
        change = sum(e.energies()) - start
        return {
            "error": work - change - e.dissipated() - e.damped(),
            "work": work,
            "damped": e.damped(),
            "force": e.force[-1],
        }


def test_work_balance_and_dissipation_converge():
    runs = [formed(ETA, n) for n in (4, 8, 16)]
    err = [r["error"] for r in runs]
    damped = [r["damped"] for r in runs]
    rates = [math.log2(abs(a) / abs(b)) for a, b in pairwise(err)]
    fall = (damped[1] - damped[0]) / (damped[2] - damped[1])
    print(f"balance errors {err}, rates {rates}; drag's dissipation {damped} (ratio {fall:.3f})")
    assert all(r["damped"] > 0.1 * r["work"] for r in runs)  # the drag matters to the balance
    assert all(1.7 < q < 2.3 for q in rates), rates
    assert 1.6 < fall < 2.5, damped


def test_tends_to_the_undamped_answer_linearly():
    f0, f1, f2 = (formed(eta, 4)["force"] for eta in (0.0, ETA / 2, ETA))
    ratio = (f2 - f0) / (f1 - f0)
    print(f"forces {f0:.6g}, {f1:.6g}, {f2:.6g}: differences ratio {ratio:.3f}")
    assert f1 > f0 and 1.8 < ratio < 2.2


def test_out_of_range_refused_and_a_large_share_warned(caplog):
    for bad, shown in ((2.0, "2"), (-1e-3, "-0.001")):
        with pytest.raises(DataError, match=rf"stabilisation = {shown} .*≤ 1 N/mm²"):
            HemispherePlugin.parse_options(
                {"tooling": {"punch_radius": 50.0, "stabilisation": bad}}, 1.0, "t"
            )
    with caplog.at_level(logging.INFO):
        share = stabilisation_share(COMM, [0.0, 1.0], [0.0, 2.0], 2 * STABILISATION_SHARE)
    assert share == pytest.approx(2 * STABILISATION_SHARE)
    warned = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warned) == (COMM.rank == 0)
    assert all("the drag carries part of the load" in r.getMessage() for r in warned)
