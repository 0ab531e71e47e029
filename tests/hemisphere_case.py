"""The hemisphere forming case the forming tests share (tests/test_hemisphere.py's): a 20 mm
punch and a 60 mm blank meshed at 4 mm, with the same tools, so the tests compile the same
forms. A test changes a tool by ``TOOLING | {…}``."""

import numpy as np

R, BLANK, H = 20.0, 60.0, 4.0
TOOLS = {
    "punch_radius": R,
    "clearance": 2.0,
    "die_lip": 2.0,
    "holder_gap": 0.4,
    "holder_pressure": 1e-3,
    "contact_stiffness": 100.0,
}
"""The punch, the die's clearance and lip, the holder's gap and pressure (1 kPa), the penalty."""
TOOLING = TOOLS | {
    "locking_angle_deg": 50.0,
    "wrinkle_tension": 1e-3,
    "wrinkle_curvature": 0.1 / R,
}
"""The tools with the wrinkling indicator's thresholds."""
FRICTION = {"friction": 0.3, "holder_pressure": 1e-2}
"""The holder with friction (10 kPa, μ = 0.3): the fibres are tensioned and the sheet wraps the
punch."""
PARAMS = {
    "fibre_stretch": {"k_l": 1e3, "k_m": 1e3},
    "shear": {"k_s": 1.0},
    "normal_bending": {"k_b": 0.1},
    "twist": {"k_t": 0.1},
}
"""The fabric the forming tests form (stiff yarns, soft shear, light bending and twist)."""


def work_balance_errors(e, stroke: float, counts) -> tuple[list, float]:
    """(∫ F ds − ΔΠ for each step count of ``counts``, ΔΠ of the last) of the plug-in ``e``
    formed to ``stroke`` from the flat blank (set back by hand before each run): the
    trapezoid rule's error of the punch work, which falls at rate 2 with the step where the
    punch force is the work conjugate of the stroke."""
    errors = []
    for steps in counts:
        e.set_load(0.0)
        e.solver.u.x.array[:] = 0.0
        start = sum(e.energies())
        e.run(stroke, steps)
        change = sum(e.energies()) - start
        errors.append(float(np.trapz(e.force, e.stroke)) - change)
    return errors, change
