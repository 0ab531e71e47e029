"""The bias-extension study of ``demos/demo_bias_extension.py`` as one library call.

(a) the fabric continuum against the Hencky lattice, the three zones, force convergence;
(b) the bi-pantographic energy (Barchiesi et al. 2020, eq. 2, Table 3 macro), the same with
the energy halved (``bipantographic_half``: eq. 2 read with the factor ½ of the spring energies,
docs/network.md, "The factor 2") and the energy with the moduli identified from the Table 3
micro lattice by numerical homogenisation, against that lattice, to ``bip_ubar`` (the paper's
whole range: 50 mm), with the clamp-offset bracket;
(c) the whole-range study of eq. (2) on nested meshes with both clamp variants
(:mod:`research.studies.bipantographic_range`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from fabricsurf.discretise.output import rank0_print
from fabricsurf.model.materials import TABLE3_MACRO, bipantographic
from fabricsurf.network import hencky_lattice, lattice_from_continuum
from fabricsurf.network.bipantographic import TABLE3, bipantographic_lattice
from fabricsurf.network.homogenize import identify_macro
from research.studies.bias_comparison import (
    EPS_EXACT,
    HENCKY_MODULI,
    LENGTH,
    WIDTH,
    ZONE_CHECK_FRAC,
    clamp_offset_bracket,
    compare,
    hencky_model,
    identification_summary,
    identified_model,
    zones_at,
)
from research.studies.bias_convergence import force_convergence
from research.studies.bipantographic_range import (
    RANGE_OPTIONS,
    convergence,
    follow_penalty,
    run_range,
)

RANGE_LOADS = [10.0, 20.0, 30.0, 40.0, 50.0]
"""mm: where the whole-range study reports force and angles."""
BRACKET_FRAC = 0.08
"""The clamp-offset bracket runs to ū ≤ 8 % of the length (the short specimen of the
identified model stiffens early)."""


@dataclass
class BiasStudySettings:
    """Settings of :func:`run_bias_study` (the demo's command line; ``quick()`` its --quick)."""

    out: Path = Path("out/bias_extension")
    h: float = 4.0
    steps: int = 10
    ubar_frac: float = 0.25
    lattice_k: int = 6
    conv_levels: str = "2,4,8"
    conv_grading: float = 0.6
    conv_steps: int = 5
    skip_bip: bool = False
    bip_ubar: float = 50.0
    bip_steps: int = 20
    range_levels: str = "2,4,8"
    is_quick: bool = False

    def quick(self) -> BiasStudySettings:
        """Coarse and fast (tests): h = 8, 4 steps, ū ≤ 10 %, k = 2, bi-pantographic to 18.7 mm
        in 4 steps, no whole-range study."""
        self.h, self.steps, self.ubar_frac, self.bip_ubar, self.bip_steps = 8.0, 4, 0.1, 18.7, 4
        self.lattice_k, self.conv_steps, self.range_levels = 2, 2, ""
        self.is_quick = True
        return self


def _hencky(s: BiasStudySettings, comm: MPI.Comm, results: dict, extras: dict) -> dict:
    eps = math.sqrt(2) * 8.5 / s.lattice_k
    m = HENCKY_MODULI
    k = lattice_from_continuum(m["k_l"], m["k_s"], m["A_g"], eps)
    lat = hencky_lattice(LENGTH, WIDTH, eps, (45.0, -45.0), **k)
    results["hencky"], extras["hencky"] = compare(
        "hencky", hencky_model(), lat, s.ubar_frac * LENGTH, s.steps, s.h, comm,
        out=s.out / "hencky")
    zones = extras["hencky"]["zones"]
    zones["check"] = zones_at(zones, ZONE_CHECK_FRAC * LENGTH)
    return {"continuum": HENCKY_MODULI, "lattice": k, "eps_mm": eps,
            "ubar_max_mm": s.ubar_frac * LENGTH, "lattice_nodes": int(lat.net.n_nodes)}


def _bipantographic(s: BiasStudySettings, comm: MPI.Comm, results: dict, extras: dict) -> dict:
    blat = bipantographic_lattice(eps=EPS_EXACT)
    ident = comm.bcast(identify_macro(eps=EPS_EXACT) if comm.rank == 0 else None, root=0)
    opts = RANGE_OPTIONS
    follow = follow_penalty()
    latres = None
    half = {k: 0.5 * v for k, v in TABLE3_MACRO.items()}
    for name, model in (("bipantographic", bipantographic()),
                        ("bipantographic_half", bipantographic(**half)),
                        ("bipantographic_identified", identified_model(ident))):
        results[name], extras[name] = compare(name, model, blat, s.bip_ubar, s.bip_steps, s.h,
                                              comm, out=s.out / name, latres=latres,
                                              snes_options=opts, on_step=follow)
        if results[name]["failure"] is None:  # else the lattice steps were cut to its range
            latres = extras[name]["lat"]
        results[name]["max_stretch"] = [f.history for f in follow.followers.values()][-1]
    n = sum(u <= BRACKET_FRAC * LENGTH + 1e-9 for u in latres["ubar"])
    extras["bipantographic_identified"]["clamp_offset"] = clamp_offset_bracket(
        identified_model(ident), latres, max(n, 1), s.h, comm, snes_options=opts)
    return {"continuum": {"K_S_N_per_mm": TABLE3_MACRO["K_S"], "K_E_Nmm": TABLE3_MACRO["K_E"],
                          "K_F_Nmm": TABLE3_MACRO["K_F"], "gamma_rad": math.pi / 6},
            "lattice": TABLE3, "eps_mm": EPS_EXACT, "ubar_max_mm": s.bip_ubar,
            "max_fibre_stretch_continuum": extras["bipantographic"]["lam_max"],
            "identified": identification_summary(ident)}


def _range(s: BiasStudySettings, comm: MPI.Comm) -> dict:
    loads = [u for u in RANGE_LOADS if u <= s.bip_ubar + 1e-9]
    out = {}
    for clamp in ("gradient", "position"):
        runs = [run_range(clamp, int(lev), s.bip_ubar, s.bip_steps, comm=comm)
                for lev in s.range_levels.split(",")]
        done = all(r["failure"] is None for r in runs)
        out[clamp] = {"runs": runs, "convergence": convergence(runs, loads) if done else None}
    return out


def run_bias_study(s: BiasStudySettings, comm: MPI.Comm = MPI.COMM_WORLD) -> tuple[dict, dict]:
    """Run (a)–(c) of the module docstring; returns (JSON summary, extras for figures)."""
    t0 = time.perf_counter()
    results, extras = {}, {}
    settings = {"length_mm": LENGTH, "width_mm": WIDTH, "h_mm": s.h, "steps": s.steps,
                "hencky": _hencky(s, comm, results, extras), "bipantographic": None}
    if not s.skip_bip:
        settings["bipantographic"] = _bipantographic(s, comm, results, extras)
    conv = force_convergence(hencky_model(), [int(v) for v in s.conv_levels.split(",")],
                             s.ubar_frac * LENGTH, s.conv_steps, grading=s.conv_grading,
                             comm=comm)
    rank0_print(comm, f"[convergence] differences {conv['differences']}, rates {conv['rates']}")
    keys = ("force_rel_diff", "angle_A_max_diff_deg", "angle_B_max_diff_deg",
            "position_rms_diff", "curves", "failure")
    summary = {nm: {kk: r[kk] for kk in keys} for nm, r in results.items()}
    for nm in ("bipantographic", "bipantographic_half", "bipantographic_identified"):
        if nm in results:
            c = results[nm]["curves"]
            summary[nm]["force_ratio_continuum_to_lattice"] = [
                fc / fl for fc, fl in zip(c["force_continuum"], c["force_lattice"])]
            summary[nm]["max_stretch"] = results[nm]["max_stretch"]
    if "bipantographic_identified" in extras:
        summary["bipantographic_identified"]["clamp_offset"] = \
            extras["bipantographic_identified"]["clamp_offset"]
    summary["three_zones"] = extras["hencky"]["zones"]
    summary["force_convergence"] = conv
    if s.range_levels and not s.skip_bip:
        summary["bipantographic_range"] = _range(s, comm)
    settings |= {"ranks": comm.size, "seconds": time.perf_counter() - t0}
    summary["settings"] = settings
    return summary, extras
