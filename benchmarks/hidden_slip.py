"""Does the diagnosis find yarn slip hidden in bias data, and from which data?

Hencky-lattice bias data (a 48 × 24 mm specimen, ±45°, a 0.8 mm lattice, fibres k_l = 30 N/mm
after slip, shear k_s = 0.5 N/mm) taken to a zone-C angle of 70° (Cao et al. 2008 eq. 13),
with slipping fibre springs at a slip tension T_s (``lattice_data(..., T_s=...)``, slip strain
ε_s = 0.002: sticking yarns of k_l + T_s/ε_s), and a control without slip whose yarns have the
sticking stiffness throughout. Each set is diagnosed from a fibre_stretch + shear baseline,
once with its field and force (noise 0.01 mm, 0.02 N) and once with the force alone. Printed:
the force's slip share at the last step, the verdict, the adequacy, the ranking's best refits
(χ², Wald p, F-test), the refitted T_s and the ties (docs/vocabulary.md, "Yarn slip in data").

    python benchmarks/hidden_slip.py [--slip 4,8] [--h 4] [--confirm 2]

(a few minutes per diagnosis on one core.)
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np

from fabricsurf.experiments import three_zone as tz
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.slip import SLIP_STRAIN

LENGTH, WIDTH, SPACING = 48.0, 24.0, 0.8
K_L, K_S = 30.0, 0.5


def path(angle_deg: float = 70.0, steps: int = 6) -> np.ndarray:
    """Displacements to a zone-C angle of ``angle_deg`` in equal steps of angle."""
    g = np.radians(np.linspace(angle_deg / steps, angle_deg, steps))
    return tz.displacement_at_angle(g, LENGTH, WIDTH)


def data(T_s: float, seed: int, sticking: bool = False):
    """Field + force lattice data with slip tension ``T_s`` (``sticking``: yarns that never
    slide, of the sticking stiffness k_l + T_s/ε_s throughout), and the same without the
    field."""
    exp = sy.template(LENGTH, WIDTH, path(), np.zeros((0, 2)), name=f"slip{T_s:g}")
    k_l, slip = (K_L + T_s / SLIP_STRAIN, 0.0) if sticking else (K_L, T_s)
    sy.lattice_data(exp, SPACING, every=6, k_l=k_l, k_s=K_S, A_g=0.0, T_s=slip, eps_s=SLIP_STRAIN)
    sy.add_noise(exp, 0.01, 0.02, seed)
    force_only = copy.deepcopy(exp)
    force_only.field_step = np.zeros(0, dtype=np.int64)
    force_only.X, force_only.u = np.zeros((0, 2)), np.zeros((0, 2))
    return exp, force_only


def report(label: str, d, seconds: float) -> None:
    rows = [r for r in d.ranking if r.get("refit_chi2") is not None]
    print(
        f"{label}: verdict {d.verdict}, adequate {d.adequate}, baseline misfit "
        f"{d.base_fit.misfit['combined']:.3f} -> {d.final_fit.misfit['combined']:.3f} "
        f"({seconds:.0f} s)",
        flush=True,
    )
    for r in rows:
        slip = r.get("refit_params", {}).get("T_s")
        print(
            f"    {r['effect']:>20}: chi2 {r['refit_chi2']:.4g} (base {d.base_fit.chi2:.4g}), "
            f"Wald p {r['wald_p']:.2g}, F-test {r['f_test_passed']}, significant "
            f"{r['significant']}" + (f", T_s {slip:.4g}" if slip is not None else ""),
            flush=True,
        )
    ties = getattr(d, "ties", None)
    if ties:
        print(f"    ties: {ties}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slip", default="4,8", help="hidden slip tensions T_s (N/mm)")
    ap.add_argument("--h", type=float, default=4.0)
    ap.add_argument("--confirm", type=int, default=2)
    a = ap.parse_args()
    print(
        f"zone-C angle at the last step: "
        f"{np.degrees(tz.zone_c_shear_angle(path()[-1], LENGTH, WIDTH)):.1f} deg",
        flush=True,
    )
    slips = [float(x) for x in a.slip.split(",")]
    for T_s, sticking in [(t, False) for t in slips] + [(slips[0], True)]:
        field, force = data(T_s, seed=7, sticking=sticking)
        label = (
            f"control (yarns of T_s = {T_s:g} that never slide)" if sticking else f"T_s = {T_s:g}"
        )
        if not sticking:
            stick, _ = data(T_s, seed=7, sticking=True)
            print(
                f"{label}: force at the last step {field.force[-1]:.4g} N, sticking net "
                f"{stick.force[-1]:.4g} N",
                flush=True,
            )
        for kind, exp in (("field + force", field), ("force only", force)):
            t0 = time.perf_counter()
            d = diagnose(
                exp,
                ["fibre_stretch", "shear"],
                h=a.h,
                confirm=a.confirm,
                max_effects=1,
                check_discretisation=False,
            )
            report(f"{label}, {kind}", d, time.perf_counter() - t0)


if __name__ == "__main__":
    main()
