# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Which effect is missing? Compare → diagnose → add → refit
#
# Run with `mpirun -n 2 python demos/demo_hidden_effect.py --out out/hidden_effect`.
#
# The "measurements" come from the Hencky spring lattice (DESIGN §5): extensional springs along
# the fibres, shear springs at the crossings and **bending springs along the fibres**. Its
# continuum limit is `fibre_stretch + shear + geodesic_bending`, so a user who models the
# fabric with `fibre_stretch + shear` only is missing in-plane fibre bending. The lattice
# response of a bias-extension test is sampled at the lattice nodes (a DIC-like point cloud),
# Gaussian noise is added, and everything is written as a DESIGN §6 measurement directory.
# Then the tool, which knows nothing about the lattice, is asked:
#
# 1. `fabricsurf compare`: how badly does `fibre_stretch + shear` (with guessed moduli) fit?
# 2. `fabricsurf diagnose --add-best`: fit the baseline, rank the missing effects, confirm.
# 3. Add the verdict and refit (Python API) — does the error fall to the noise level?

# %%
import argparse
import json
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.cli import main as cli
from fabricsurf.discretise.output import rank0_print, write_json
from fabricsurf.inverse import synthetic as sy
from fabricsurf.inverse.forward import ForwardModel
from fabricsurf.inverse.data import load_experiment, write_experiment
from fabricsurf.inverse.fit import fit
from fabricsurf.model.terms import parse_terms

comm = MPI.COMM_WORLD
ap = argparse.ArgumentParser()
ap.add_argument("--out", default="out/hidden_effect")
ap.add_argument("--spacing", type=float, default=1.0, help="lattice spacing (mm)")
ap.add_argument("--noise", type=float, default=0.01, help="displacement noise std (mm)")
ap.add_argument("--h", type=float, default=3.0, help="element size of the fitted model (mm)")
ap.add_argument("--quick", action="store_true", help="smaller lattice data (test suite)")
args, _ = ap.parse_known_args()
out = Path(args.out)
say = lambda *a: rank0_print(comm, *a)  # noqa: E731
t_start = time.perf_counter()

# %% [markdown]
# ## 1. Measurement data from the lattice with a hidden effect
# Half-size bias specimen 94 × 60 mm, ±45° fibres, k_l = 30 N/mm, k_s = 0.5 N/mm,
# A_g = 20 N·mm (lattice k_e, k_sh, k_b from `lattice_from_continuum`), grip displacements
# 1.5, 3, 4.5, 6 mm, noise 0.01 mm on displacements and 0.02 N on forces.

# %%
TRUTH = {"k_l": 30.0, "k_s": 0.5, "A_g": 20.0}
data = out / "data"
if comm.rank == 0:
    exp = sy.template(94.0, 60.0, [1.5, 3.0, 4.5, 6.0], np.zeros((0, 2)), name="hencky-hidden")
    sy.lattice_data(exp, args.spacing, every=5, **TRUTH)
    sy.add_noise(exp, args.noise, 0.02, seed=2024)
    write_experiment(data, exp, overwrite=True)
comm.barrier()
exp = load_experiment(data)
say(f"data: {len(exp.X)} field rows, {len(exp.steps)} steps, force {np.round(exp.force, 3)} N")

# %% [markdown]
# ## 2. Compare a first guess of the baseline model

# %%
guess = out / "guess.json"
write_json(comm, guess, {"fibre_stretch": {"k_l": 20.0, "k_m": 20.0}, "shear": {"k_s": 1.0}})
comm.barrier()
cli(["compare", str(data), "--params", str(guess), "--h", str(args.h), "--out",
     str(out / "compare")])

# %% [markdown]
# ## 3. Diagnose: fit the baseline, rank the missing effects, confirm, add the best

# %%
cli(["diagnose", str(data), "--terms", "fibre_stretch,shear", "--h", str(args.h), "--out",
     str(out / "diagnose"), "--add-best"])
diag = json.loads((out / "diagnose" / "diagnosis.json").read_text()) if comm.rank == 0 else None
diag = comm.bcast(diag)

# %% [markdown]
# ## 4. Add the verdict and refit with the Python API (a few lines)

# %%
verdict = diag["verdict"]
terms = "fibre_stretch,shear" + (f",{verdict}" if verdict else "")
start = {**diag["baseline"]["params"], **({verdict: {"A_g": 1.0}} if verdict else {})}
fm = ForwardModel(exp, parse_terms(terms, start), h=args.h)
refit = fit(fm, verbose=False)
write_json(comm, out / "refit.json", refit.as_dict())

# %%
b, a = diag["baseline"], refit.misfit
say("\n=== account ===")
say(f"baseline fibre_stretch+shear: combined misfit {b['misfit']:.3f} (1 = noise level)")
for r in diag["ranking"]:
    say(f"  candidate {r['effect']:17s} score {r['score']:9.1f}  refit misfit "
        f"{r['refit_misfit'] if r['refit_misfit'] is None else round(r['refit_misfit'], 3)}"
        f"  significant {r['significant']}")
say(f"verdict: {verdict}; not identifiable from planar data: "
    f"{[r['effect'] for r in diag['not_identifiable']]}")
say(f"after adding {verdict}: combined misfit {a['combined']:.3f}, field RMS "
    f"{a['field_rms']:.4f} mm (noise {exp.noise_std} mm), force RMS {a['force_rms']:.4f} N")
for n, v, s in zip(refit.names, refit.values, refit.std):
    say(f"  {n:22s} = {v:8.4g} ± {s:.2g}   lattice value {TRUTH[n.split('.')[1][:3]]:g}"
        if n.split(".")[1][:3] in TRUTH else f"  {n:22s} = {v:8.4g} ± {s:.2g}")
summary = {"truth": TRUTH, "baseline_misfit": b["misfit"], "verdict": verdict,
           "ranking": [(r["effect"], r["score"], r["refit_misfit"]) for r in diag["ranking"]],
           "refit_misfit": a["combined"], "refit_params": refit.params(),
           "refit_std": refit.as_dict()["std"], "adequate": diag["adequate"],
           "path": diag["path"],
           "seconds": time.perf_counter() - t_start}
write_json(comm, out / "summary.json", summary)
say(f"figures in {out}/compare, {out}/diagnose; summary in {out / 'summary.json'} "
    f"({summary['seconds']:.0f} s)")
