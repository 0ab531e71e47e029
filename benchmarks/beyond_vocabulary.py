"""Calibration of the search beyond the vocabulary (docs/diagnosis.md, "Beyond the vocabulary").

Continuum bias tests of our own generator (40 × 20 mm, ±45°, fibre_stretch k_l = k_m = 30 N/mm,
shear k_s = 0.5 N/mm, 8 × 4 field points and the force at 1, 2 and 3 mm, data on a 1.5 mm mesh
(``--data-h``), diagnosed at h = 3 mm from fibre_stretch + shear with confirm 2 and one named
effect at most, the h/2 check on): nothing hidden, geodesic bending hidden (A_g = 15 N·mm: in
the vocabulary, so a feature found is a false alarm too), a shear–tension coupling ½k_c
γ²((λ−1)+(μ−1)) hidden (k_c = 3 or 5 N/mm) or a crimp interchange k_x (λ−1)(μ−1) hidden (k_x = 8
or 12 N/mm), each a continuum user term, at two noise levels and several noise seeds. Each data
set is diagnosed, then searched as the pipeline would
(:func:`~fabricsurf.inverse.diagnosis.beyond.search_beyond`: not on a mesh too coarse; when the
final model is adequate, only if its gate opens) and, when the pipeline did not search, searched
again with ``force=True``. Printed: one line per data set and the table: the false-alarm rate on
the null data and the detection rate of each hidden effect (the feature found, alone or in a tie
holding it), by the pipeline and forced.

    .venv/bin/python benchmarks/beyond_vocabulary.py [--seeds 2] [--first-seed 0] [--json OUT]
    .venv/bin/python benchmarks/beyond_vocabulary.py --table OUT1.json OUT2.json  # merge
"""

from __future__ import annotations

import argparse
import itertools
import logging
import time
from dataclasses import dataclass
from typing import ClassVar

from mpi4py import MPI

from fabricsurf.inverse.diagnosis.beyond import search_beyond
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0
from fabricsurf.model.term import Term
from fabricsurf.model.terms import EFFECTS, make_term
from fabricsurf.model.user_effects import register_effect
from research.rows import read_rows, save_rows

logger = logging.getLogger(__name__)


@dataclass
class HiddenShearTension(Term):
    """½k_c γ²((λ−1)+(μ−1)): the user's term of docs/usage.md, hidden in the data."""

    k_c: float = 1.0
    name: ClassVar[str] = "hidden_shear_tension"
    units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}

    def density(self, kin, p):
        return 0.5 * p["k_c"] * kin.gamma**2 * ((kin.lam - 1) + (kin.mu - 1))


@dataclass
class HiddenCrimpInterchange(Term):
    """k_x (λ−1)(μ−1): the two fibre stretches coupled (crimp interchange), hidden."""

    k_x: float = 1.0
    name: ClassVar[str] = "hidden_crimp_interchange"
    units: ClassVar[dict[str, str]] = {"k_x": "N/mm"}

    def density(self, kin, p):
        return p["k_x"] * (kin.lam - 1) * (kin.mu - 1)


HIDDEN = {
    "none": (None, None),
    "geodesic_bending": (make_term("geodesic_bending", A_g=15.0), None),
    "shear_tension k_c=3": (HiddenShearTension(k_c=3.0), "shear_tension_plus"),
    "shear_tension k_c=5": (HiddenShearTension(k_c=5.0), "shear_tension_plus"),
    "crimp_interchange k_x=8": (HiddenCrimpInterchange(k_x=8.0), "crimp_interchange_plus"),
    "crimp_interchange k_x=12": (HiddenCrimpInterchange(k_x=12.0), "crimp_interchange_plus"),
}
"""Each case: the term hidden in the data and the feature that names it (None: a null case, in
which any feature found is a false alarm; geodesic bending is in the vocabulary)."""
NULLS = ("none", "geodesic_bending")
NOISES = (0.01, 0.02)


def data(hidden: str, noise: float, seed: int, h_data: float = 1.5):
    """The module docstring's bias test with ``hidden`` (a user term, registered only while
    the data are made), made at ``h_data``."""
    exp = sy.template(40.0, 20.0, [1.0, 2.0, 3.0], sy.grid_points(40.0, 20.0, 8, 4))
    model = [make_term("fibre_stretch", k_l=30.0, k_m=30.0), make_term("shear", k_s=0.5)]
    term = HIDDEN[hidden][0]
    user = term is not None and term.name not in EFFECTS
    if user:
        register_effect(type(term))
    try:
        sy.continuum_data(exp, model + ([term] if term is not None else []), h=h_data)
    finally:
        if user:
            EFFECTS.unregister(term.name)
    return sy.add_noise(exp, noise, 0.02, seed)


def names(rec: dict) -> list[str]:
    """The features a search found, with those it could not tell from the first."""
    return [n for f in rec["found"] for n in [f["feature"], *f["indistinguishable_from"]]]


def one(hidden: str, noise: float, seed: int, h_data: float = 1.5) -> dict:
    t0 = time.perf_counter()
    exp = data(hidden, noise, 1000 + seed, h_data)
    with detail():
        d = diagnose(exp, ["fibre_stretch", "shear"], h=3.0, confirm=2, max_effects=1)
        rec = search_beyond(d, exp)
        forced = rec if rec["searched"] else search_beyond(d, exp, force=True)
    truth = HIDDEN[hidden][1]
    row = {
        "hidden": hidden,
        "noise": noise,
        "h_data": h_data,
        "seed": seed,
        "named": d.verdict_text(),
        "adequate": d.adequate,
        "too_coarse": d.too_coarse(),
        "misfit": d.path[-1]["misfit"],
        "searched": rec["searched"],
        "found": names(rec),
        "forced_found": names(forced),
        "outcome": rec["outcome"],
        "forced_outcome": forced["outcome"],
        "modulus": [f["modulus"] for f in forced["found"]],
        "gate": forced.get("gate"),
        "first_round": [
            [q["effect"], q["score"], q.get("delta_chi2")] for q in forced.get("rounds", [[]])[0]
        ][:3],
        "seconds": time.perf_counter() - t0,
    }
    row["hit"] = truth in row["found"] if truth else bool(row["found"])
    row["forced_hit"] = truth in row["forced_found"] if truth else bool(row["forced_found"])
    rank0(
        logger,
        MPI.COMM_WORLD,
        f"{hidden:17s} noise {noise:<5g} seed {seed}: named "
        f"{row['named']}, misfit {row['misfit']:.3f}, adequate {d.adequate}; pipeline: "
        f"{rec['outcome']}; forced: {forced['outcome']} ({row['seconds']:.0f} s)",
    )
    return row


def truth_modulus(hidden: str) -> float | None:
    """The hidden coupling's modulus (None for a null case)."""
    term, feature = HIDDEN[hidden]
    return next(iter(term.values().values())) if feature else None


def counts(sel: list[dict], found: str) -> tuple[int, int]:
    """(alone, in a tie): the data sets whose search (``found``: "found" or "forced_found")
    named the hidden feature first, without and with indistinguishable others."""
    truth = HIDDEN[sel[0]["hidden"]][1] if sel else None
    first = [r for r in sel if r[found] and r[found][0] == truth]
    return sum(len(r[found]) == 1 for r in first), sum(len(r[found]) > 1 for r in first)


def covered(sel: list[dict]) -> int:
    """The forced searches whose 95 % interval of the found modulus holds the hidden one."""
    k = truth_modulus(sel[0]["hidden"]) if sel else None
    return (
        sum(
            bool(r["modulus"])
            and r["forced_hit"]
            and r["modulus"][0]["ci95"][0] <= k <= r["modulus"][0]["ci95"][1]
            for r in sel
        )
        if k is not None
        else 0
    )


def table(rows: list[dict]) -> None:
    def say(msg: str) -> None:
        rank0(logger, MPI.COMM_WORLD, msg)

    say(
        "\n| hidden | noise (mm) | sets | named verdict | searched | pipeline: alone + tie"
        " | forced: alone + tie | another feature first (forced) | k in its 95 % interval |"
    )
    say("|---|---|---|---|---|---|---|---|---|")
    for hidden, noise in itertools.product(HIDDEN, NOISES):
        sel = [r for r in rows if r["hidden"] == hidden and r["noise"] == noise]
        if not sel:
            continue
        null = hidden in NULLS
        pipe = (sum(r["hit"] for r in sel), 0) if null else counts(sel, "found")
        forced = (sum(r["forced_hit"] for r in sel), 0) if null else counts(sel, "forced_found")
        other = sum(bool(r["forced_found"]) and not r["forced_hit"] for r in sel)
        say(
            f"| {hidden} | {noise:g} | {len(sel)} | {sum(r['named'] is not None for r in sel)}"
            f" | {sum(r['searched'] for r in sel)} | "
            + (
                f"{pipe[0]} false | {forced[0]} false | – | – |"
                if null
                else f"{pipe[0]} + {pipe[1]} | {forced[0]} + {forced[1]} | {other} | "
                f"{covered(sel)}/{forced[0] + forced[1]} |"
            )
        )
    null = [r for r in rows if r["hidden"] in NULLS]
    for label, key in (("pipeline", "hit"), ("forced", "forced_hit")):
        say(
            f"false alarms ({label}): {sum(r[key] for r in null)}/{len(null)}; detections: "
            + "; ".join(
                f"{h} {sum(r[key] for r in rows if r['hidden'] == h)}/"
                f"{sum(r['hidden'] == h for r in rows)}"
                for h in HIDDEN
                if h not in NULLS
            )
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument(
        "--cases", default=",".join(HIDDEN), help=f"comma-separated, of: {', '.join(HIDDEN)}"
    )
    ap.add_argument(
        "--data-h",
        type=float,
        default=1.5,
        help="the mesh the data are made on (mm); 0.75 puts it below the h/2 check's own mesh, "
        "so that judging a feature one mesh finer moves towards the data's model",
    )
    ap.add_argument("--json", default=None, help="write the rows to this file")
    ap.add_argument(
        "--table",
        nargs="*",
        default=None,
        help="only print the table of these --json files (no runs)",
    )
    args = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    if args.table:
        table(read_rows(args.table))
        return
    rows = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        for hidden, noise in itertools.product(args.cases.split(","), NOISES):
            rows.append(one(hidden, noise, seed, args.data_h))
            save_rows(args.json, rows)  # after each, so a long run can stop
    table(rows)


if __name__ == "__main__":
    main()
