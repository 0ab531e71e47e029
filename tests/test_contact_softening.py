"""The punch's softened contact (``contact_softening`` ε: the penalty's ⟨−d⟩ replaced by the
softplus ε ln(1 + e^(−d/ε)); experiments/forming/tools.py, docs/tool_surfaces.md, "A box").

Checks that can fail independently of each other, on the tests' hemisphere set-up with a
flat-topped punch (a box 28 × 20 mm with 2 mm fillets, given as a surface):

* the punch force is the work conjugate of the stroke under the softened law too: from the
  equilibrium at s = 0 (the softened punch presses the flat blank already there, and the run
  records that force), the punch work equals the change of the energy, the trapezoid rule's
  error falling at rate 2 with the step (measured 0.262, 0.0598 N·mm at ε = 0.02 mm);
* the softened answer tends to the plain penalty's as ε → 0, at least at first order: each
  halving of ε (0.02, 0.01, 0.005 mm) at least halves the punch force's difference to the
  plain penalty's (the softplus exceeds ⟨−d⟩ by at most ε ln 2; measured ratios 2.96, 3.36,
  the last difference 0.12 % of the force);
* ε = 0 is the plain penalty (the forms of before: every other forming test); an ε outside
  [0, 0.01 die_lip] is refused naming the key.
"""

import math

import numpy as np
import pytest
from hemisphere_case import BLANK, TOOLING, H
from mpi4py import MPI

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming.surfaces import analytic
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist

COMM = MPI.COMM_WORLD
STROKE = 4.0
PUNCH = analytic.RoundedBox((14.0, 10.0, 20.0), 2.0, centre=(0.0, 0.0, -20.0))


def model():
    return [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]


def experiment(softening: float) -> HemispherePlugin:
    opts = {**TOOLING, "punch_surface": PUNCH, "contact_softening": softening}
    return HemispherePlugin(
        PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model(), H, COMM
    )


def formed(e: HemispherePlugin, steps: int) -> tuple[float, float]:
    """(punch work − change of the energy, final force) of a run from the equilibrium at s = 0
    (the softened punch presses the flat blank already there: the run starts from it)."""
    e.solver.reset()
    e.set_load(0.0)
    e.solver.solve()
    start = sum(e.energies())
    e.run(STROKE, steps)
    return float(np.trapz(e.force, e.stroke)) - (sum(e.energies()) - start), e.force[-1]


def test_work_balance_with_softening():
    with experiment(0.02) as e:
        coarse, _ = formed(e, 4)
        fine, force = formed(e, 8)
    rate = math.log2(abs(coarse) / abs(fine))
    print(f"balance errors {coarse:.4g}, {fine:.4g} (rate {rate:.2f}); force {force:.6g} N")
    assert force > 0.1
    assert 1.8 < rate < 2.2, (coarse, fine)


def test_tends_to_the_penalty_at_least_at_first_order():
    forces = {}
    for eps in (0.0, 0.005, 0.01, 0.02):
        with experiment(eps) as e:
            forces[eps] = formed(e, 4)[1]
    d = [forces[eps] - forces[0.0] for eps in (0.005, 0.01, 0.02)]
    print(f"forces {forces}; differences {d}, ratios {d[1] / d[0]:.3f}, {d[2] / d[1]:.3f}")
    assert 0 < d[0] < 2e-3 * forces[0.0]
    assert d[1] / d[0] > 1.8 and d[2] / d[1] > 1.8


def test_softening_out_of_range_refused():
    tables = {"tooling": {"punch_radius": 50.0, "contact_softening": 1.0}}
    with pytest.raises(DataError, match=r"contact_softening = 1 .* 0\.01 die_lip \(= 0\.1 mm\)"):
        HemispherePlugin.parse_options(tables, 1.0, "t")
    with pytest.raises(DataError, match=r"contact_softening = -0\.001"):
        HemispherePlugin.parse_options(
            {"tooling": {"punch_radius": 50.0, "contact_softening": -1e-3}}, 1.0, "t"
        )
