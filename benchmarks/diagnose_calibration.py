"""Calibration of the diagnosis: false-alarm rate and detection power (docs/diagnosis.md).

Null data sets: Hencky-lattice bias tests whose continuum limit is the complete model
fibre_stretch + shear + geodesic_bending, diagnosed with that model: any verdict is a false
alarm. They span two lattice spacings, both fibre-stiffness regimes (soft fibres k_l/k_s = 60,
nearly inextensible k_l/k_s = 2500) and noise from half to three times the lattice–continuum
form error (measured first: the misfit of the continuum at the true moduli against noise-free
lattice data). Power: geodesic bending hidden from a fibre_stretch + shear baseline, at bending
lengths 1–32 mm, in both regimes (soft: 1 mm lattice, noise 0.01 mm; stiff: 0.5 mm lattice,
noise equal to its form error); the signal is what the hidden effect adds to the misfit,
√(misfit_base² − misfit_floor²) in noise units, with misfit_floor that of the complete model at
the true moduli against the same noisy data (noise and form error); a detection is the verdict
geodesic_bending. Prints the rates and writes OUT/power.png and OUT/calibration.json.

    mpirun -n 2 .venv/bin/python benchmarks/diagnose_calibration.py --out out/calibration
    # or the two parts as two processes into the same OUT (memory, see --parts):
    mpirun -n 2 .venv/bin/python benchmarks/diagnose_calibration.py --out OUT --parts null
    mpirun -n 2 .venv/bin/python benchmarks/diagnose_calibration.py --out OUT --parts power
"""

from __future__ import annotations

import argparse
import itertools
import json
import logging
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import write_json
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0
from fabricsurf.network import ConvergenceError

logger = logging.getLogger(__name__)

LENGTH, WIDTH = 60.0, 30.0
REGIMES = {"soft": (30.0, 0.5), "stiff": (1000.0, 0.4)}
COMPLETE = ["fibre_stretch", "shear", "geodesic_bending"]


def lattice(spacing, k_l, k_s, A_g, strain, steps=3):
    path = list(np.linspace(strain * LENGTH / steps, strain * LENGTH, steps))
    exp = sy.template(LENGTH, WIDTH, path, np.zeros((0, 2)), name="calibration")
    return sy.lattice_data(exp, spacing, k_l=k_l, k_s=k_s, A_g=A_g, every=2)


def truth_model(k_l, k_s, A_g):
    return full_model(
        COMPLETE,
        {
            "fibre_stretch": {"k_l": k_l, "k_m": k_l},
            "shear": {"k_s": k_s},
            "geodesic_bending": {"A_g": A_g},
        },
    )


def form_error(exp, k_l, k_s, A_g, h) -> float:
    """RMS field difference (mm) between the continuum at the true moduli and the lattice."""
    p = ForwardModel(exp, truth_model(k_l, k_s, A_g), h=h).run()
    return float(np.sqrt(np.nanmean((p.u - exp.u[:, :2]) ** 2)))


def noisy(exp, std, seed):
    return sy.noisy_copy(exp, std, 0.01 * float(np.max(np.abs(exp.force))) + 1e-3, seed)


def best_candidate(d) -> dict:
    """The confirmed candidate's Δχ², the share of the baseline's excess it removes and its F
    statistic against the variance left (the two parts of the significance rule)."""
    row = next((r for r in d.ranking if r.get("refit_chi2") is not None), None)
    if row is None:
        return {}
    n = d.base_fit.misfit["n"]
    p = sum(nm.split(".")[0] in d.baseline for nm in d.base_fit.names)
    k = sum(nm.split(".")[0] == row["effect"] for nm in d.base_fit.names)
    base, new = d.base_fit.chi2, row["refit_chi2"]
    return {
        "effect": row["effect"],
        "delta_chi2": base - new,
        "share_of_excess": sg.share_of_excess(base, p, new, n),
        "F": sg.f_statistic(base, p, new, p + k, n),
        "significant": row["significant"],
    }


def null_sets(a, comm, say) -> list[dict]:
    """Diagnoses of the complete model on its own lattice data (module docstring)."""
    null = []
    for (regime, (k_l, k_s)), spacing in itertools.product(REGIMES.items(), (1.0, 0.5)):
        strain = 0.05 if regime == "soft" else 0.12
        A_g = k_s * 25.0
        clean = lattice(spacing, k_l, k_s, A_g, strain)
        e_f = form_error(clean, k_l, k_s, A_g, a.h)
        for ratio, seed in itertools.product((0.5, 1.0, 3.0), range(a.seeds)):
            with detail():
                d = diagnose(
                    noisy(clean, ratio * e_f, 100 + seed),
                    COMPLETE,
                    h=a.h,
                    confirm=1,
                    max_effects=1,
                    check_discretisation=False,
                    comm=comm,
                )
            null.append(
                {
                    "regime": regime,
                    "spacing": spacing,
                    "noise_over_form": ratio,
                    "form_error_mm": e_f,
                    "verdict": d.verdict,
                    "adequate": d.adequate,
                    "misfit": d.final_fit.misfit["combined"],
                    "best": best_candidate(d),
                }
            )
            say(
                f"null {regime} eps={spacing} noise/form={ratio}: verdict {d.verdict}, "
                f"adequate {d.adequate}, misfit {null[-1]['misfit']:.3f}"
            )
    return null


def power_sets(a, comm, say) -> list[dict]:
    """Diagnoses with geodesic bending hidden (module docstring)."""
    power = []
    k_l, k_s = REGIMES["stiff"]
    stiff_noise = form_error(lattice(0.5, k_l, k_s, k_s * 25.0, 0.12), k_l, k_s, k_s * 25.0, a.h)
    lengths = [float(x) for x in a.bending_lengths.split(",")]
    for (regime, (k_l, k_s)), l_b, seed in itertools.product(
        REGIMES.items(), lengths, range(a.seeds)
    ):
        spacing, strain, noise = (1.0, 0.05, 0.01) if regime == "soft" else (0.5, 0.12, stiff_noise)
        try:
            clean = lattice(spacing, k_l, k_s, k_s * l_b**2, strain)
        except ConvergenceError as e:  # reported, left out of the rates
            power.append(
                {
                    "regime": regime,
                    "spacing": spacing,
                    "l_b_mm": l_b,
                    "seed": seed,
                    "lattice_failed": str(e),
                }
            )
            say(f"power {regime} l_b={l_b}: the lattice generator failed ({e})")
            continue
        exp = noisy(clean, noise, 200 + seed)
        with detail():
            d = diagnose(
                exp,
                ["fibre_stretch", "shear"],
                h=a.h,
                confirm=1,
                max_effects=1,
                check_discretisation=False,
                comm=comm,
            )
        fm = ForwardModel(exp, truth_model(k_l, k_s, k_s * l_b**2), h=a.h, comm=comm)
        floor = fm.misfit(fm.run())["combined"]
        base = d.base_fit.misfit["combined"]
        signal = float(np.sqrt(max(base**2 - floor**2, 0.0)))
        power.append(
            {
                "regime": regime,
                "spacing": spacing,
                "l_b_mm": l_b,
                "seed": seed,
                "noise_mm": noise,
                "signal_over_noise": signal,
                "baseline_misfit": base,
                "floor_misfit": floor,
                "detected": d.verdict == "geodesic_bending",
                "verdict": d.verdict,
                "best": best_candidate(d),
            }
        )
        say(
            f"power {regime} l_b={l_b} signal/noise {signal:.2f} (baseline {base:.3f}, floor "
            f"{floor:.3f}): verdict {d.verdict}"
        )
    return power


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/calibration")
    ap.add_argument("--h", type=float, default=2.0, help="model element size (mm)")
    ap.add_argument("--seeds", type=int, default=2, help="noise draws per configuration")
    ap.add_argument(
        "--parts",
        default="null,power",
        help="null, power or both: each diagnosis leaves 30 MB (soft, 1 mm lattice) "
        "to about 1 GB (stiff, 0.5 mm) per rank behind, not freed (cause not "
        "found), and one process for everything ran out of 24 GB; the parts "
        "(and --bending-lengths) can run as separate processes into one OUT",
    )
    ap.add_argument(
        "--bending-lengths",
        default="1,2,4,8,16,32",
        help="hidden l_b (mm) of the power part; rows of other lengths already in "
        "OUT/calibration.json are kept",
    )
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    say = lambda s: rank0(logger, comm, s)  # noqa: E731
    parts = set(a.parts.split(","))
    if not parts or parts - {"null", "power"}:
        raise SystemExit(f"diagnose_calibration: --parts {a.parts!r}: give null, power or both")
    out = Path(a.out)
    old = {}
    if (out / "calibration.json").exists():
        old = json.loads((out / "calibration.json").read_text())
    null = null_sets(a, comm, say) if "null" in parts else old.get("null", [])
    power = old.get("power", [])
    if "power" in parts:
        new = power_sets(a, comm, say)
        done = {(r["regime"], r["l_b_mm"], r["seed"]) for r in new}
        power = [
            r for r in power if "seed" in r and (r["regime"], r["l_b_mm"], r["seed"]) not in done
        ] + new
    fa = float(np.mean([r["verdict"] is not None for r in null])) if null else float("nan")
    strong = [r for r in power if r.get("signal_over_noise", 0.0) > 3]
    det = float(np.mean([r["detected"] for r in strong])) if strong else float("nan")
    say(f"false alarms: {fa:.3f} over {len(null)} null data sets (target ≤ 0.05)")
    say(f"detection where signal > 3 noise: {det:.3f} over {len(strong)} (target ≥ 0.9)")
    write_json(
        comm,
        out / "calibration.json",
        {"null": null, "power": power, "false_alarm_rate": fa, "detection": det},
    )
    if comm.rank == 0:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5, 3.6))
        for regime, mark in (("soft", "o"), ("stiff", "s")):
            rows = [r for r in power if r["regime"] == regime and "detected" in r]
            ax.semilogx(
                [max(r["signal_over_noise"], 0.05) for r in rows],
                [float(r["detected"]) for r in rows],
                mark,
                mfc="none",
                label=regime,
            )
        ax.axvline(3.0, color="k", ls="--", label="signal = 3 noise")
        ax.set(
            xlabel="signal of the hidden geodesic bending / noise",
            ylabel="detected",
            title=f"false alarms {fa:.2f} over {len(null)}",
        )
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / "power.png", dpi=110)


if __name__ == "__main__":
    main()
