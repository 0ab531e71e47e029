"""The search beyond the vocabulary on lattice data (docs/lattice_effects.md): the counterpart,
on data the continuum did not make, of benchmarks/beyond_vocabulary.py.

Hencky-lattice bias tests (fabricsurf.network, spacing 0.25 mm, every 400th node a point: 32
points and the force at 1, 2 and 3 mm) of a 40 × 20 mm specimen at ±45°, fibres k_l = 30 N/mm,
shear k_s = 0.5 N/mm, with one effect hidden in the springs:

* ``shear_tension``: the crossings' shear stiffness k_s(1 + c(e_L + e_M)), c = 10 (the
  continuum ½k_c γ²((λ−1)+(μ−1)) with k_c = c·k_s = 5 N/mm);
* ``crimp``: the crimp interchange k_x e_L e_M at each crossing, k_x = 12 N/mm;
* ``compression_soft``: fibres with (1 − s)k_l in compression, s = 0.8 (the continuum
  fibre_stretch at 6 N/mm plus ½·24·max(λ−1,0)²);

and two null cases: nothing hidden, and geodesic bending A_g = 15 N·mm (in the vocabulary: the
diagnosis may add it, any feature found is a false alarm). A bias test does not compress the
fibres (the lattice's smallest fibre strain is −1e-14), so compression-soft fibres alone leave
the data unchanged; with the crimp interchange they are compressed (to −1.5 %): the second
round (``--cases`` of ``SECOND_ROUND``) hides crimp + compression-soft fibres, with crimp
alone as its null, and diagnoses from fibre_stretch + shear + the user's crimp term (the loop's
second turn, after the crimp was found and added). The lattice's bending springs are not
``geodesic_bending`` at finite stretch (docs/network.md: their curvatures divided by λ, μ):
``geodesic_bending, my_lattice_bending known`` diagnoses the bending data from fibre_stretch +
shear + that exact form as a user's term, a null with nothing the continuum lacks. Noise 0.01
and 0.02 mm (force 0.02 N), noise seeds 1000 + seed. Each set is diagnosed from fibre_stretch +
shear at h = 3 mm (confirm 2, one named effect at most, the h/2 check on), searched as the
pipeline does and, when the pipeline did not search, forced; for the hidden effects the user's
own term (the classes below, a module of the user's own registered with ``register_effect``) is
then added to the baseline and all fitted together: misfit and moduli before (the named
diagnosis's final model) and after. Runs serially or under ``mpirun -n 2``; a set takes 20–140
s.

``--held-out``: the configuration kept aside until the end, fibres at ±40° on a 48 × 20 mm
specimen (the same moduli, path 1.2, 2.4, 3.6 mm).

    .venv/bin/python benchmarks/lattice_beyond.py [--seeds 3] [--first-seed 0] [--json OUT]
        [--cases "none;crimp k_x=12"] [--held-out] [--pipeline]
    .venv/bin/python benchmarks/lattice_beyond.py --table OUT1.json OUT2.json  # merge
"""

from __future__ import annotations

import argparse
import itertools
import logging
import time
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import ufl
from mpi4py import MPI

from fabricsurf.inverse.diagnosis.beyond import search_beyond
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0
from fabricsurf.model.term import Term
from fabricsurf.model.terms import EFFECTS, make_term
from fabricsurf.model.user_effects import register_effect
from research.rows import read_rows, save_rows

logger = logging.getLogger(__name__)

K_L, K_S, SPACING, EVERY, H = 30.0, 0.5, 0.25, 400, 3.0
BASE = ["fibre_stretch", "shear"]
NOISES = (0.01, 0.02)


# ------------------------------------------------------------ the user's own module
@dataclass
class MyShearTension(Term):
    """½k_c γ²((λ−1)+(μ−1)): shear stiffening under fibre tension."""

    k_c: float = 1.0
    name: ClassVar[str] = "my_shear_tension"
    units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}

    def density(self, kin, p):
        return 0.5 * p["k_c"] * kin.gamma**2 * ((kin.lam - 1) + (kin.mu - 1))


@dataclass
class MyCrimp(Term):
    """k_x (λ−1)(μ−1): crimp interchange."""

    k_x: float = 1.0
    name: ClassVar[str] = "my_crimp"
    units: ClassVar[dict[str, str]] = {"k_x": "N/mm"}

    def density(self, kin, p):
        return p["k_x"] * (kin.lam - 1) * (kin.mu - 1)


@dataclass
class MyTensionOnly(Term):
    """½k_t [max(λ−1,0)² + max(μ−1,0)²]: the fibres stiffer in tension than in compression."""

    k_t: float = 1.0
    name: ClassVar[str] = "my_tension_only"
    units: ClassVar[dict[str, str]] = {"k_t": "N/mm"}

    def density(self, kin, p):
        return (
            0.5
            * p["k_t"]
            * (ufl.max_value(kin.lam - 1, 0.0) ** 2 + ufl.max_value(kin.mu - 1, 0.0) ** 2)
        )


@dataclass
class MyLatticeBending(Term):
    """½A_b [(g_l·p/λ)² + (g_m·q/μ)²]: the lattice's own bending springs in the continuum limit
    (docs/network.md: geodesic_bending's density with its curvatures divided by the stretch)."""

    A_b: float = 1.0
    name: ClassVar[str] = "my_lattice_bending"
    order: ClassVar[int] = 2
    units: ClassVar[dict[str, str]] = {"A_b": "N·mm"}

    def density(self, kin, p):
        return 0.5 * p["A_b"] * ((kin.geodesic_l / kin.lam) ** 2 + (kin.geodesic_m / kin.mu) ** 2)


CASES = {
    "none": ({}, None, None, None, ()),
    "geodesic_bending": ({"A_g": 15.0}, None, None, None, ()),
    "shear_tension c=10": ({"c_st": 10.0}, "shear_tension_plus", MyShearTension, 10.0 * K_S, ()),
    "crimp k_x=12": ({"k_x": 12.0}, "crimp_interchange_plus", MyCrimp, 12.0, ()),
    "compression_soft s=0.8": ({"s_comp": 0.8}, "tension_stiff", MyTensionOnly, 0.8 * K_L, ()),
    "crimp, my_crimp known": ({"k_x": 12.0}, None, None, None, (MyCrimp,)),
    "geodesic_bending, my_lattice_bending known": (
        {"A_g": 15.0},
        None,
        None,
        None,
        (MyLatticeBending,),
    ),
    "crimp + compression_soft, my_crimp known": (
        {"k_x": 12.0, "s_comp": 0.8},
        "tension_stiff",
        MyTensionOnly,
        0.8 * K_L,
        (MyCrimp,),
    ),
}
"""Each case: the lattice keywords (of ``lattice_data``), the feature that names it (None: a
null case), the user's term and its modulus in the data, and the user's terms already known
(registered and in the baseline: the second round of the loop, after the crimp was found)."""
NULLS = (
    "none",
    "geodesic_bending",
    "crimp, my_crimp known",
    "geodesic_bending, my_lattice_bending known",
)
SECOND_ROUND = (
    "crimp, my_crimp known",
    "crimp + compression_soft, my_crimp known",
    "geodesic_bending, my_lattice_bending known",
)
CONFIGS = {
    "main": (40.0, 20.0, (45.0, -45.0), [1.0, 2.0, 3.0]),
    "held-out": (48.0, 20.0, (40.0, -40.0), [1.2, 2.4, 3.6]),
}


def clean_data(case: str, config: str):
    """Noise-free lattice data (the lattice is solved once per case and configuration)."""
    length, width, angles, path = CONFIGS[config]
    exp = sy.template(length, width, path, np.zeros((0, 2)), angles=angles)
    kw = {"A_g": 0.0} | CASES[case][0]
    return sy.lattice_data(exp, SPACING, k_l=K_L, k_s=K_S, every=EVERY, **kw)


def names(rec: dict) -> list[str]:
    """The features a search found, with those it could not tell from the first."""
    return [n for f in rec["found"] for n in [f["feature"], *f["indistinguishable_from"]]]


def with_user_term(exp, case: str, d, rec: dict) -> dict:
    """Fit the baseline (fibre_stretch + shear and the terms already known) + the user's term
    (registered while fitted), started from the baseline's moduli and the feature's modulus
    when the search found it."""
    _, feature, cls, _, known = CASES[case]
    base = d.base_fit.params()
    found = [f for f in rec["found"] if f["feature"] == feature]
    k0 = found[0]["modulus"]["value"] if found else 1.0
    register_effect(cls)
    try:
        (pname,) = cls.units
        model = [make_term(n, **base[n]) for n in BASE + [c.name for c in known]]
        model += [cls(**{pname: max(k0, 1e-3)})]
        with ForwardModel(exp, model, h=H) as fm, detail():
            r = fit(fm)
    finally:
        EFFECTS.unregister(cls.name)
    return {"misfit": r.misfit["combined"], "moduli": r.params()}


def one(case: str, config: str, noise: float, seed: int, clean, pipeline: bool = False) -> dict:
    """One data set: diagnosed, searched as the pipeline does (its gate decides) and, unless
    ``pipeline``, forced when the pipeline did not search and fitted with the user's term."""
    t0 = time.perf_counter()
    exp = sy.add_noise(replace(clean), noise, 0.02, 1000 + seed)
    _, truth, cls, k_true, known = CASES[case]
    for c in known:
        register_effect(c)
    try:
        with detail():
            d = diagnose(exp, BASE + [c.name for c in known], h=H, confirm=2, max_effects=1)
            rec = search_beyond(d, exp)
            forced = rec if rec["searched"] or pipeline else search_beyond(d, exp, force=True)
        user = with_user_term(exp, case, d, forced) if cls is not None and not pipeline else None
    finally:
        for c in known:
            EFFECTS.unregister(c.name)
    row = {
        "case": case,
        "config": config,
        "noise": noise,
        "seed": seed,
        "named": d.verdict_text(),
        "adequate": bool(d.adequate),
        "too_coarse": bool(d.too_coarse()),
        "misfit_base": d.path[0]["misfit"],
        "misfit": d.path[-1]["misfit"],
        "moduli": d.final_fit.params(),
        "searched": rec["searched"],
        "found": names(rec),
        "forced_found": names(forced),
        "outcome": rec["outcome"],
        "forced_outcome": forced["outcome"],
        "modulus": [f["modulus"] for f in forced["found"]],
        "misfit_feature": [f["refit_misfit"] for f in forced["found"]],
        "gate": forced.get("gate"),
        "first_round": [
            [q["effect"], q["score"], q.get("delta_chi2"), q.get("finer_mesh_delta_chi2")]
            for q in forced.get("rounds", [[]])[0]
        ][:3],
    }
    row["searched"] = bool(row["searched"])
    row["hit"] = truth in row["found"] if truth else bool(row["found"])
    row["forced_hit"] = truth in row["forced_found"] if truth else bool(row["forced_found"])
    if user is not None:
        row["user"] = user | {"k_true": k_true}
    row["seconds"] = time.perf_counter() - t0
    user = row.get("user")
    rank0(
        logger,
        MPI.COMM_WORLD,
        f"{config} {case:22s} noise {noise:<5g} seed {seed}: named {row['named']}, misfit "
        f"{row['misfit_base']:.3f} -> {row['misfit']:.3f}, adequate {d.adequate}; pipeline: "
        f"{rec['outcome']}; forced: {forced['outcome']}"
        + (f"; with the user's term: misfit {user['misfit']:.3f}, {user['moduli']}" if user else "")
        + f" ({row['seconds']:.0f} s)",
    )
    return row


def counts(sel: list[dict], found: str) -> tuple[int, int]:
    """(alone, in a tie): the sets whose search named the hidden feature first."""
    truth = CASES[sel[0]["case"]][1] if sel else None
    first = [r for r in sel if r[found] and r[found][0] == truth]
    return sum(len(r[found]) == 1 for r in first), sum(len(r[found]) > 1 for r in first)


def table(rows: list[dict]) -> None:
    def say(msg: str) -> None:
        rank0(logger, MPI.COMM_WORLD, msg)

    for config in CONFIGS:
        crow = [r for r in rows if r["config"] == config]
        if not crow:
            continue
        say(
            f"\n{config}: | hidden | noise (mm) | sets | named verdict | searched | pipeline: "
            "alone + tie | forced: alone + tie | features named (forced) | misfit base → named "
            "→ with the user's term | user's modulus (true) |"
        )
        say("|---|---|---|---|---|---|---|---|---|---|")
        for case, noise in itertools.product(CASES, NOISES):
            sel = [r for r in crow if r["case"] == case and r["noise"] == noise]
            if not sel:
                continue
            null = case in NULLS
            pipe = (sum(r["hit"] for r in sel), 0) if null else counts(sel, "found")
            forced = (sum(r["forced_hit"] for r in sel), 0) if null else counts(sel, "forced_found")
            feats = sorted({r["forced_found"][0] for r in sel if r["forced_found"]})
            mis = (
                f"{np.mean([r['misfit_base'] for r in sel]):.3f} → "
                f"{np.mean([r['misfit'] for r in sel]):.3f}"
            )
            if null:
                cells = (
                    f"{pipe[0]} false | {forced[0]} false | {', '.join(feats) or '–'} | {mis} | – |"
                )
            else:
                cls, fitted = CASES[case][2], [r["user"] for r in sel if "user" in r]
                ks = [u["moduli"][cls.name][next(iter(cls.units))] for u in fitted]
                user = (
                    f"{np.mean([u['misfit'] for u in fitted]):.3f} | "
                    f"{min(ks):.3g}–{max(ks):.3g} ({CASES[case][3]:g}) |"
                    if fitted
                    else "– | – |"
                )
                cells = (
                    f"{pipe[0]} + {pipe[1]} | {forced[0]} + {forced[1]} | "
                    f"{', '.join(feats) or '–'} | {mis} → " + user
                )
            say(
                f"| {case} | {noise:g} | {len(sel)} | {sum(r['named'] is not None for r in sel)}"
                f" | {sum(r['searched'] for r in sel)} | " + cells
            )
        null = [r for r in crow if r["case"] in NULLS]
        for label, key in (("pipeline", "hit"), ("forced", "forced_hit")):
            say(
                f"{config}: false alarms ({label}) {sum(r[key] for r in null)}/{len(null)}; "
                "detections: "
                + "; ".join(
                    f"{c} {sum(r[key] for r in crow if r['case'] == c)}/"
                    f"{sum(r['case'] == c for r in crow)}"
                    for c in CASES
                    if c not in NULLS
                )
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument(
        "--cases",
        default=";".join(c for c in CASES if c not in SECOND_ROUND),
        help=f"semicolon-separated, of: {'; '.join(CASES)}",
    )
    ap.add_argument("--held-out", action="store_true", help="the configuration kept aside")
    ap.add_argument(
        "--pipeline",
        action="store_true",
        help="the pipeline only: no forced search, no fit with the user's term",
    )
    ap.add_argument("--json", default=None, help="write the rows to this file")
    ap.add_argument("--table", nargs="*", default=None, help="only print these --json files")
    args = ap.parse_args()
    configure()
    if args.table:
        table(read_rows(args.table))
        return
    config = "held-out" if args.held_out else "main"
    rows = []
    for case in args.cases.split(";"):
        t0 = time.perf_counter()
        clean = clean_data(case, config)
        rank0(logger, MPI.COMM_WORLD, f"{case}: lattice data in {time.perf_counter() - t0:.0f} s")
        for seed, noise in itertools.product(
            range(args.first_seed, args.first_seed + args.seeds), NOISES
        ):
            rows.append(one(case, config, noise, seed, clean, args.pipeline))
            save_rows(args.json, rows)  # after each, so a long run can stop
    table(rows)


if __name__ == "__main__":
    main()
