"""An elastic bias test gives the same answer whatever the number of load steps (issue 52;
docs/theory.md, "Converged load steps").

With stiff yarns (K/k_s = 1e9) the first residual of a load step is the Dirichlet lifting of
the grip increment, ~K·Δū, and SNES's relative test (rtol = 1e-10 of it) accepted iterates
whose grip force depended on the step size: 70.8 / 79.0 / 70.3 N for 1 / 2 / 5 steps on
200 × 119 mm at h = 2 mm (ū = 20 mm). SNESSolver now goes on from such an iterate until its
Newton correction is below STEP_RTOL = 1e-8 of the state.

Runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``.
"""

import numpy as np
import pytest

from fabricsurf.discretise.snes import STEP_RTOL
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.model.terms import FibreStretch, Shear

L, W, UBAR, K_S, RATIO = 100.0, 60.0, 10.0, 0.5, 1e9
STEPS = (1, 2, 5)
FLOOR = 1e-7
"""Relative scatter of the grip force between solves driven to the rounding floor of the
residual (re-solved until it stagnates; 200 × 119 mm, h = 2 mm, K/k_s = 1e9: 70.292890 to
70.292896 N over 1, 2, 5 steps)."""


def final_force(h: float, steps: int, step_rtol: float) -> tuple[float, str]:
    b = BiasExtension(
        [FibreStretch(k_l=RATIO * K_S, k_m=RATIO * K_S), Shear(k_s=K_S)],
        L,
        W,
        h,
        snes_options={"step_rtol": step_rtol},
    )
    res = b.run(UBAR, steps)
    return res.force[-1], b.discretisation["mesh_kind"]


@pytest.mark.parametrize("h", [6.0, 4.0])
def test_force_does_not_depend_on_the_number_of_steps(h):
    """1, 2 and 5 steps give grip forces within 10 × FLOOR of each other (measured: 6e-8 and
    1.2e-7 at h = 4 and 6 mm, aligned meshes of 3.54 and 7.07 mm); with the relative test alone
    (step_rtol = 0, the old acceptance) the same runs differ by 4.3e-4 and 3.2e-3, so this
    set-up still shows the fault the check removes."""
    forces, kinds = zip(*(final_force(h, n, STEP_RTOL) for n in STEPS))
    assert set(kinds) == {"aligned"}
    spread = np.ptp(forces) / np.mean(forces)
    print(f"h = {h}: forces {forces} N, spread {spread:.2e}")
    assert spread < 10 * FLOOR, forces
    old = [final_force(h, n, 0.0)[0] for n in STEPS]
    assert np.ptp(old) / np.mean(old) > 1e-4, old
