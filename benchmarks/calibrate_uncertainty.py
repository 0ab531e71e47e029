"""Calibration of the moduli's intervals and of the significance rule (docs/uncertainty.md).

Hencky-lattice bias data (60 × 30 mm, lattice spacing 1 mm, every other node measured, three
steps), soft fibres (k_l/k_s = 60) and nearly inextensible ones (k_l/k_s = 2500), geodesic
bending of bending length 5 mm, with white noise or DIC-like noise (a Gaussian random field of
correlation length ``--corr`` mm) whose standard deviation is the lattice–continuum form
error (the RMS field difference of the continuum at the lattice's moduli):

- ``coverage``: the complete model fitted; the share of the 95 % intervals of the
  identifiable moduli that contain the lattice's (k_l, k_m = k_l, k_s, A_g), new and
  classical ((JᵀJ)⁻¹ at the stated noise), with the median relative half-widths and the
  normalised errors z = (value − truth)/σ (σ = half-width / t95: RMS 1 when calibrated).
  The lattice–continuum form error of one configuration is the same for every noise draw, so
  draws of one configuration are not independent trials of the interval: ``--design
  configurations`` varies the specimen, the lattice spacing and the bending length instead
  (:data:`CONFIGURATIONS`, one draw each, white and DIC noise alternating), and ``--design
  pairs`` fits each configuration together with a specimen PAIR_SCALE times larger, as a
  user with two specimen sizes does: the spread of the moduli between the specimens is then
  the model-form part;
- ``null``: diagnoses of the complete model on its own lattice data (any verdict is a false
  alarm), the confirmed candidate's statistics recorded so that the rule in use (Wald and
  F-test), the Wald test alone, Wald with the quarter-of-the-excess part and the old F-test rule
  are counted on the same sets;
- ``detect``: geodesic bending hidden from a fibre_stretch + shear baseline at bending lengths
  ``--bending-lengths``; the signal √(misfit_base² − misfit_floor²) in noise units as in
  benchmarks/diagnose_calibration.py; a detection is the verdict geodesic_bending.

Every part appends its rows to OUT/uncertainty_calibration.json (parts can run as separate
processes, which also frees the memory each diagnosis leaves behind):

    mpirun -n 2 .venv/bin/python benchmarks/calibrate_uncertainty.py --part coverage --count 4
    mpirun -n 2 .venv/bin/python benchmarks/calibrate_uncertainty.py --part null --count 10
    mpirun -n 2 .venv/bin/python benchmarks/calibrate_uncertainty.py --part detect --count 2
"""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import write_json
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardModel, ForwardSet
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0
from fabricsurf.network import ConvergenceError

logger = logging.getLogger(__name__)

LENGTH, WIDTH = 60.0, 30.0
REGIMES = {"soft": (30.0, 0.5, 0.05), "stiff": (1000.0, 0.4, 0.12)}  # k_l, k_s, strain
BENDING_LENGTH = 5.0
COMPLETE = ["fibre_stretch", "shear", "geodesic_bending"]
NOISE_KINDS = ("white", "dic")
PAIR_SCALE = 1.5
"""The second specimen of a pair is this much larger (the same lattice and spacing)."""
CONFIGURATIONS = [  # regime, length, width (mm), lattice spacing (mm), bending length (mm)
    (regime, length, width, spacing, l_b)
    for regime in REGIMES
    for (length, width, spacing), l_b in zip(
        [
            (60.0, 30.0, 1.0),
            (48.0, 24.0, 1.0),
            (60.0, 30.0, 1.5),
            (72.0, 24.0, 1.5),
            (54.0, 36.0, 1.0),
            (66.0, 22.0, 1.0),
            (45.0, 30.0, 1.5),
            (80.0, 40.0, 2.0),
            (40.0, 20.0, 0.8),
            (64.0, 32.0, 2.0),
        ],
        (3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 4.5, 6.5, 3.5, 5.5),
    )
]


def truth(k_l: float, k_s: float, l_b: float) -> dict:
    return {
        "fibre_stretch": {"k_l": k_l, "k_m": k_l},
        "shear": {"k_s": k_s},
        "geodesic_bending": {"A_g": k_s * l_b**2},
    }


def lattice(
    k_l: float,
    k_s: float,
    strain: float,
    l_b: float,
    steps: int = 3,
    size: tuple[float, float] = (LENGTH, WIDTH),
    spacing: float = 1.0,
):
    path = list(np.linspace(strain * size[0] / steps, strain * size[0], steps))
    exp = sy.template(*size, path, np.zeros((0, 2)), name="calibration")
    return sy.lattice_data(exp, spacing, k_l=k_l, k_s=k_s, A_g=k_s * l_b**2, every=2)


def form_error(exp, params: dict, h: float, comm) -> float:
    """RMS field difference (mm) of the continuum at the lattice's moduli."""
    with ForwardModel(exp, full_model(COMPLETE, params), h=h, comm=comm) as fm:
        p = fm.run()
    return float(np.sqrt(np.nanmean((p.u - exp.u[:, :2]) ** 2)))


def noisy(exp, std: float, kind: str, seed: int, corr: float):
    s_F = 0.01 * float(np.max(np.abs(exp.force))) + 1e-3
    return sy.noisy_copy(exp, std, s_F, seed, corr if kind == "dic" else 0.0)


def configuration_cases(a, comm, pairs: bool = False):
    """One case per configuration of :data:`CONFIGURATIONS` (module docstring): its specimen
    alone, or with ``pairs`` also a second one PAIR_SCALE times larger with the same lattice
    (then the noisy data, form errors and clean data are lists, one entry per specimen)."""
    scales = (1.0, PAIR_SCALE) if pairs else (1.0,)
    for k, (regime, length, width, spacing, l_b) in enumerate(CONFIGURATIONS):
        k_l, k_s, strain = REGIMES[regime]
        params = truth(k_l, k_s, l_b)
        try:
            clean = [
                lattice(k_l, k_s, strain, l_b, size=(f * length, f * width), spacing=spacing)
                for f in scales
            ]
        except ConvergenceError as e:
            rank0(logger, comm, f"configuration {k}: the lattice generator failed ({e}); left out")
            continue
        if pairs:
            for j, c in enumerate(clean):
                c.name = f"specimen {j + 1}"
        e_f = [form_error(c, params, a.h, comm) for c in clean]
        kind = NOISE_KINDS[k % 2]
        base = 3000 if pairs else 2000
        data = [
            noisy(c, e, kind, base + len(scales) * (a.seed + k) + j, a.corr)
            for j, (c, e) in enumerate(zip(clean, e_f))
        ]
        size = f"{length:g}x{width:g}" + (f" and x{PAIR_SCALE:g}" if pairs else "")
        label = f"{regime} {size} a={spacing:g} l_b={l_b:g}"
        if pairs:
            yield label, kind, a.seed + k, data, params, e_f, clean
        else:
            yield label, kind, a.seed + k, data[0], params, e_f[0], clean[0]


def cases(a, comm, l_b: float = BENDING_LENGTH):
    """(regime, noise kind, seed, noisy data, true moduli, form error, clean data) for every
    case."""
    design = getattr(a, "design", "seeds")
    if design in ("configurations", "pairs"):
        yield from configuration_cases(a, comm, pairs=design == "pairs")
        return
    for regime, (k_l, k_s, strain) in REGIMES.items():
        params = truth(k_l, k_s, l_b)
        clean = lattice(k_l, k_s, strain, l_b)
        e_f = form_error(clean, params, a.h, comm)
        for kind, seed in itertools.product(NOISE_KINDS, range(a.seed, a.seed + a.count)):
            yield (
                regime,
                kind,
                seed,
                noisy(clean, e_f, kind, 1000 + seed, a.corr),
                params,
                e_f,
                clean,
            )


def coverage_row(res, params: dict, best: dict) -> dict:
    """Per modulus: inside the new interval, inside the classical one, relative widths, the
    normalised error z; and against ``best``, the noise-free fit's moduli on the same mesh
    (the continuum that best represents this lattice): inside the interval, and
    z_statistical = (value − best)/σ_statistical, the test of the statistical part alone."""
    u = res.uncertainty()["moduli"]
    naive = np.sqrt(np.diag(res.statistical.cov_naive))
    out = {}
    for k, n in enumerate(res.free):
        name = res.names[n]
        t, p = name.split(".")
        true = params[t][p]
        m = u[name]
        lo, hi = m["ci95"]
        out[name] = {
            "truth": true,
            "value": m["value"],
            "identifiable": m["identifiable"],
            "covered": bool(lo <= true <= hi),
            "z": (m["value"] - true) / max((hi - lo) / 2 / res.statistical.t95(), 1e-300),
            "best_continuum": best[name],
            "covered_best": bool(lo <= best[name] <= hi),
            "z_statistical": (m["value"] - best[name]) / max(m["std_statistical"], 1e-300),
            "covered_classical": bool(abs(m["value"] - true) <= 1.96 * naive[k]),
            "half_width_rel": (hi - lo) / 2 / true,
            "half_width_rel_classical": 1.96 * naive[k] / true,
            "std_statistical": m["std_statistical"],
            "systematic_mesh": m["systematic_mesh"],
            "systematic_model": m["systematic_model"],
        }
    return out


def fitted(exp, params: dict, h: float, comm, mesh: bool = True):
    """The complete model fitted to ``exp`` (one experiment or a list, one set of moduli) from
    1.3 × the lattice's moduli (with the mesh part when ``mesh``)."""
    start = {t: {p: 1.3 * v for p, v in q.items()} for t, q in params.items()}
    make = ForwardSet if isinstance(exp, list) else ForwardModel
    with make(exp, full_model(COMPLETE, start), h=h, comm=comm) as fm:
        free = [i for i, (t, _) in enumerate(fm.params) if t.name in COMPLETE]
        with detail():  # one of many fits: its iterations are detail
            res = fit(fm, free, scale_start=False, space="linear")
            if mesh:
                res.check_mesh(fm)
    return res


def part_coverage(a, comm, say) -> list[dict]:
    rows = []
    for regime, kind, seed, exp, params, e_f, clean in cases(a, comm):
        t0 = time.perf_counter()
        res = fitted(exp, params, a.h, comm)
        ref = fitted(clean, params, a.h, comm, mesh=False)
        best = dict(zip(ref.names, ref.values))
        st = res.statistical
        rows.append(
            {
                "regime": regime,
                "design": a.design,
                "noise": kind,
                "seed": seed,
                "noise_mm": e_f,
                "moduli": coverage_row(res, params, best),
                "design_effect": st.design_effect,
                "blocks": st.n_blocks,
                "misfit": res.misfit["combined"],
                "seconds": time.perf_counter() - t0,
            }
        )
        cov = {n: (m["covered"], m["covered_classical"]) for n, m in rows[-1]["moduli"].items()}
        say(
            f"coverage {regime} {kind} {seed}: (new, classical) {cov}; deff "
            f"{st.design_effect:.2f}; {rows[-1]['seconds']:.0f} s"
        )
    return rows


def candidate(d) -> dict:
    """The confirmed candidate's statistics under the four rules (module docstring)."""
    row = next((r for r in d.ranking if r.get("refit_chi2") is not None), None)
    if row is None:
        return {}
    gain = d.base_fit.chi2 - row["refit_chi2"] > 0
    share = row["share_of_excess"] >= sg.FRACTION_OF_EXCESS
    wald = row["wald_p"] < 1.0 - sg.LEVEL
    return {
        "effect": row["effect"],
        "wald_p": row["wald_p"],
        "share_of_excess": row["share_of_excess"],
        "f_test_passed": row["f_test_passed"],
        "rule_wald_and_f": bool(gain and wald and row["f_test_passed"]),
        "rule_wald": bool(gain and wald),
        "rule_wald_and_share": bool(gain and wald and share),
        "rule_old": bool(gain and row["f_test_passed"] and share),
    }


def part_null(a, comm, say) -> list[dict]:
    rows = []
    for regime, kind, seed, exp, _, e_f, _ in cases(a, comm):
        t0 = time.perf_counter()
        with detail():
            d = diagnose(
                exp,
                COMPLETE,
                h=a.h,
                confirm=1,
                max_effects=1,
                check_discretisation=False,
                comm=comm,
            )
        rows.append(
            {
                "regime": regime,
                "noise": kind,
                "seed": seed,
                "noise_mm": e_f,
                "verdict": d.verdict,
                "candidate": candidate(d),
                "seconds": time.perf_counter() - t0,
            }
        )
        say(f"null {regime} {kind} {seed}: verdict {d.verdict}; {rows[-1]['candidate']}")
    return rows


def part_detect(a, comm, say) -> list[dict]:
    rows = []
    for l_b in (float(x) for x in a.bending_lengths.split(",")):
        try:
            for regime, kind, seed, exp, params, e_f, _ in cases(a, comm, l_b):
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
                fm = ForwardModel(exp, full_model(COMPLETE, params), h=a.h, comm=comm)
                floor = fm.misfit(fm.run())["combined"]
                fm.close()
                base = d.base_fit.misfit["combined"]
                signal = float(np.sqrt(max(base**2 - floor**2, 0.0)))
                rows.append(
                    {
                        "regime": regime,
                        "noise": kind,
                        "seed": seed,
                        "l_b_mm": l_b,
                        "signal_over_noise": signal,
                        "verdict": d.verdict,
                        "candidate": candidate(d),
                    }
                )
                say(
                    f"detect {regime} {kind} l_b={l_b} {seed}: signal {signal:.2f}, verdict "
                    f"{d.verdict}; {rows[-1]['candidate']}"
                )
        except ConvergenceError as e:
            say(f"detect l_b={l_b}: the lattice generator failed ({e}); left out")
    return rows


RULES = ("rule_wald_and_f", "rule_wald", "rule_wald_and_share", "rule_old")


def summary(data: dict) -> dict:
    """The rates over every row in OUT (module docstring)."""
    out = {}
    cov = data.get("coverage", [])
    for key in ("covered", "covered_classical"):
        hits = [m[key] for r in cov for m in r["moduli"].values() if m["identifiable"]]
        out[key] = float(np.mean(hits)) if hits else None
    for key in ("half_width_rel", "half_width_rel_classical"):
        w = [m[key] for r in cov for m in r["moduli"].values() if m["identifiable"]]
        out["median_" + key] = float(np.median(w)) if w else None
    out["coverage_intervals"] = sum(m["identifiable"] for r in cov for m in r["moduli"].values())
    for key in ("z", "z_statistical"):
        z = [m[key] for r in cov for m in r["moduli"].values() if m["identifiable"] and key in m]
        out["rms_" + key] = float(np.sqrt(np.mean(np.square(z)))) if z else None
    best = [
        m["covered_best"]
        for r in cov
        for m in r["moduli"].values()
        if m["identifiable"] and "covered_best" in m
    ]
    out["covered_best_continuum"] = float(np.mean(best)) if best else None
    for design in ("seeds", "configurations", "pairs"):
        hits = [
            m["covered"]
            for r in cov
            if r.get("design", "seeds") == design
            for m in r["moduli"].values()
            if m["identifiable"]
        ]
        out[f"covered_{design}"] = float(np.mean(hits)) if hits else None
        out[f"intervals_{design}"] = len(hits)
    null = data.get("null", [])
    for rule in RULES:
        out["false_alarms_" + rule] = (
            float(np.mean([bool(r["candidate"].get(rule)) for r in null])) if null else None
        )
    out["null_sets"] = len(null)
    strong = [r for r in data.get("detect", []) if r["signal_over_noise"] > 3]
    for rule in RULES:
        out["detection_" + rule] = (
            float(
                np.mean(
                    [
                        r["candidate"].get("effect") == "geodesic_bending"
                        and bool(r["candidate"].get(rule))
                        for r in strong
                    ]
                )
            )
            if strong
            else None
        )
    out["strong_sets"] = len(strong)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/calibrate_uncertainty")
    ap.add_argument("--part", required=True, choices=("coverage", "null", "detect"))
    ap.add_argument("--count", type=int, default=2, help="noise draws per regime and kind")
    ap.add_argument(
        "--design",
        default="seeds",
        choices=("seeds", "configurations", "pairs"),
        help="coverage over noise draws of two configurations, over the "
        "configurations of CONFIGURATIONS (one draw each), or over the same "
        "as pairs of specimen sizes fitted together",
    )
    ap.add_argument(
        "--seed", type=int, default=0, help="first noise draw (runs that add to OUT give a new one)"
    )
    ap.add_argument("--h", type=float, default=3.0, help="model element size (mm)")
    ap.add_argument("--corr", type=float, default=3.0, help="DIC noise correlation length")
    ap.add_argument("--bending-lengths", default="2,5,10", help="hidden l_b (mm) of detect")
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    say = lambda s: rank0(logger, comm, s)  # noqa: E731
    path = Path(a.out) / "uncertainty_calibration.json"
    data = json.loads(path.read_text()) if path.exists() else {}
    run = {"coverage": part_coverage, "null": part_null, "detect": part_detect}[a.part]
    data[a.part] = data.get(a.part, []) + run(a, comm, say)
    data["summary"] = summary(data)
    for k, v in data["summary"].items():
        say(f"{k}: {v}")
    write_json(comm, path, data)


if __name__ == "__main__":
    main()
