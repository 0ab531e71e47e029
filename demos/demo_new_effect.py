# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # An effect the vocabulary does not have: diagnose → search beyond → write it → refit
#
# Run with `mpirun -n 2 python demos/demo_new_effect.py --out out/new_effect [--quick]`.
#
# Woven fabrics stiffen in shear when their yarns are under tension: tension presses the yarns
# together at the crossovers, and biaxial bias tests measure a shear stiffness that grows with
# the fibre tension. No named effect of the vocabulary (`fabricsurf terms`) has that coupling.
# Here the "measurements" are a bias-extension test of a sheet that has it,
#
#     W = ½k_l(λ−1)² + ½k_m(μ−1)² + ½k_s γ² + ½k_c γ²((λ−1) + (μ−1)),
#
# λ, μ the stretches of the two fibre families and γ the shear angle (docs/theory.md), made by
# the continuum with the coupling written as a user's term and then hidden: the tool is asked
# with the vocabulary only. What it does, as a user would:
#
# 1. `fabricsurf.diagnose` with `fibre_stretch + shear` as the baseline: it adds the best named
#    effect it finds and still calls the model **not adequate** (the misfit stays above the
#    noise level): the named effects do not explain these data.
# 2. `search_beyond(diagnosis, exps)` (docs/diagnosis.md, "Beyond the vocabulary") searches a
#    library of energy features no named effect has, with the diagnosis's own machinery and a
#    Bonferroni-corrected significance rule, and names the form it found: γ²((λ−1)+(μ−1)), its
#    share of the excess misfit, its modulus with a 95 % interval, and the Term source.
# 3. That source is written to a module of the user's own (`my_effects.py` in `--out`) and
#    loaded as `--effects my_effects.py` would load it (`fabricsurf.effects_from`), which checks
#    its declarations and that its density is linear in its modulus.
# 4. The model with the new term is diagnosed again from the start: now it is **adequate**
#    (the misfit at the noise level) and nothing named is missing any more; the same term
#    through `fabricsurf fit --effects my_effects.py`; a figure of the force and field errors
#    before and after; the fitted model's bias test as XDMF.

# %%
import json
import logging
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from mpi4py import MPI

import fabricsurf as fsf
from fabricsurf.cli import main as cli
from fabricsurf.cli.demo import demo_parser, parse, require, verify
from fabricsurf.discretise.output import on_rank0, write_json
from fabricsurf.inverse.diagnosis.beyond import search_beyond, summary_lines
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import detail, rank0

comm = MPI.COMM_WORLD
logger = logging.getLogger(__name__)
ap = demo_parser(__doc__, "out/new_effect")
ap.add_argument("--k-c", type=float, default=5.0, help="the hidden coupling k_c (N/mm)")
ap.add_argument("--noise", type=float, default=0.01, help="displacement noise std (mm)")
ap.add_argument("--seed", type=int, default=21, help="noise seed")
args = parse(ap)  # --quick: no h/2 check of the mesh, no XDMF, no other noise draws (section 1)
out = args.out


def say(message: str) -> None:
    rank0(logger, comm, message)


t_start = time.perf_counter()

# %% [markdown]
# ## 1. Measurement data with a coupling outside the vocabulary
# A 40 × 20 mm bias specimen, fibres at ±45°, k_l = k_m = 30 N/mm, k_s = 0.5 N/mm and the
# shear–tension coupling k_c = 5 N/mm; grip displacements 1, 2 and 3 mm; displacements at
# 8 × 4 points (a coarse DIC grid) and the force at each step, noise 0.01 mm and 0.02 N. The
# data are the continuum's on a 1.5 mm mesh, the tool works at h = 3 mm (its h/2 check finds
# the discretisation error inside the noise band). This is the set-up of
# benchmarks/beyond_vocabulary.py (docs/diagnosis.md, "Calibration"), where the search, forced,
# named this coupling first in all 24 data sets with k_c = 3 or 5 N/mm, and the pipeline (which
# searches only when the diagnosis leaves an excess) in 12 of 12 at this noise level, 4 of 12 at
# 0.02 mm.
#
# The hidden term is written exactly as a user writes an effect of their own (docs/usage.md,
# "Adding your own effect"): a `Term` subclass with its modulus, its unit and its density.
# It is registered only while the data are made, so the diagnosis below cannot use it.
#
# `--quick` makes the same data and runs the same loop without the h/2 check of the mesh (the
# diagnosis then gives the discretisation no credit, which the data do not need at h = 3 mm),
# without the XDMF of the fitted bias test and without the other noise draws of section 7; its
# declared checks are the full mode's.

# %%


@dataclass
class HiddenShearTension(fsf.Term):
    """½k_c γ²((λ−1)+(μ−1)): shear stiffening under fibre tension (hidden in the data)."""

    k_c: float = 1.0
    name: ClassVar[str] = "hidden_shear_tension"
    units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}

    def density(self, kin, p):
        return 0.5 * p["k_c"] * kin.gamma**2 * ((kin.lam - 1) + (kin.mu - 1))


L, W, H_DATA, H = 40.0, 20.0, 1.5, 3.0
TRUTH = {
    "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
    "shear": {"k_s": 0.5},
    "hidden_shear_tension": {"k_c": args.k_c},
}
BASE = ["fibre_stretch", "shear"]
data = out / "data"
exp = sy.template(L, W, [1.0, 2.0, 3.0], sy.grid_points(L, W, 8, 4), name="shear-tension")
fsf.register_effect(HiddenShearTension, "the demo's hidden effect")
try:
    truth_terms = [fsf.make_term(n, **p) for n, p in TRUTH.items()]
    with detail():
        sy.continuum_data(exp, truth_terms, h=H_DATA, comm=comm)
finally:
    fsf.EFFECTS.unregister(HiddenShearTension.name)
clean, clean_force = exp, exp.force.copy()
exp = sy.noisy_copy(clean, args.noise, 0.02, args.seed)
on_rank0(comm, fsf.write_experiment, data, exp, overwrite=True)
comm.barrier()
exp = fsf.load_experiment(data)  # what a user has: the measurement directory
say(
    f"data: {len(exp.X)} field rows, {len(exp.steps)} steps, force {np.round(exp.force, 3)} N "
    f"(noise {exp.noise_std} mm, {exp.force_noise_std} N)"
)

# %% [markdown]
# ## 2. The diagnosis with the named vocabulary
# Baseline `fibre_stretch + shear`; every effect the planar data can see is a candidate; the
# best two are confirmed by refits and one is added at most, as in the benchmark. Adequate means
# χ²/ν within the band of the noise (docs/diagnosis.md, "Adequate").

# %%
with detail():
    named = fsf.diagnose(
        exp, BASE, h=H, confirm=2, max_effects=1, check_discretisation=not args.quick, comm=comm
    )
say(
    f"named diagnosis: {named.outcome()}; baseline misfit {named.path[0]['misfit']:.3f}, "
    f"final {'+'.join(named.terms)} misfit {named.path[-1]['misfit']:.3f}; "
    f"adequate {named.adequate}"
)

# %% [markdown]
# ## 3. Search beyond the vocabulary
# The search takes the finished diagnosis (its final model and meshes) and the experiments, and
# tests each feature of the library at the level 0.001/m (m features: Bonferroni). It reports
# the form found, the share Δχ²/(χ² − ν) of the excess misfit it removes, its modulus k with a
# 95 % interval (for this feature k plays the part of k_c), where on the specimen the misfit
# falls, and the source of a `Term` to paste into a module of one's own.

# %%
with detail():
    beyond = search_beyond(named, exp, comm=comm)
for line in summary_lines(beyond):
    say(line)
require(beyond["found"], f"the search found nothing: {beyond['outcome']}")
found = beyond["found"][0]

# %% [markdown]
# ## 4. The found term as a module of the user's own
# The source goes into `my_effects.py` unchanged. `fabricsurf.effects_from` loads it as the
# command line's `--effects my_effects.py` does: the file is imported, its `Term` subclasses are
# checked (a name not taken, a unit per modulus, defaults) and its density is checked to be
# linear in its modulus on 32 random kinematic states, W(2p) = 2W(p) and W(p + q) = W(p) + W(q)
# to 10⁻¹⁰, which the exact sensitivities of fit and diagnose rely on. To show that the check
# does refuse, a variant with k² in place of k is loaded too.

# %%
module = out / "my_effects.py"
on_rank0(comm, module.write_text, found["source"], encoding="utf-8")
nonlinear = out / "not_linear.py"
on_rank0(
    comm,
    nonlinear.write_text,
    found["source"].replace('p["k"] *', 'p["k"] ** 2 *').replace(found["feature"], "squared"),
    encoding="utf-8",
)
comm.barrier()
try:
    with fsf.effects_from([nonlinear]):
        refused = None
except ValueError as e:
    refused = str(e)
say(f"the k² variant: {'refused: ' + refused if refused else 'accepted (!)'}")

# %% [markdown]
# ## 5. The model with the new term, diagnosed again
# Inside the `with` block the new effect is a term like any other: `--terms`, `--params`, the
# fit and the diagnosis accept it. The diagnosis starts again from `fibre_stretch + shear +` the
# new term (the named effect the first diagnosis added was its stand-in): it fits that model,
# scores and refits every named effect as a candidate again, and adds one only if the model is
# not adequate. The same as
# `fabricsurf diagnose DATA --effects my_effects.py --terms fibre_stretch,shear,<name> ...`.

# %%
with fsf.effects_from([module]) as loaded:
    new = loaded[0]
    origin = fsf.EFFECTS.origin(new)  # registered: its declarations and linearity passed
    start = {n: named.final_fit.params()[n] for n in BASE} | {new: {"k": found["modulus"]["value"]}}
    with detail():
        after = fsf.diagnose(
            exp,
            BASE + [new],
            h=H,
            params=start,
            confirm=2,
            max_effects=1,
            check_discretisation=not args.quick,
            comm=comm,
        )
    fitted = {n: after.final_fit.params()[n] for n in after.terms}
    k_after = after.as_dict()["final"]["moduli"][f"{new}.k"]
    still = [q["effect"] for q in after.ranking if q["significant"]]
    if not args.quick:  # the fitted model's bias test to the last grip displacement: XDMF
        model = [fsf.make_term(n, **fitted[n]) for n in after.terms]
        with detail():
            fsf.BiasExtension(model, L, W, H).run(float(exp.path[-1]), 6, out=out / "fitted_bias")
say(
    f"with {new}: {after.outcome()}; misfit {after.final_fit.misfit['combined']:.3f}, adequate "
    f"{after.adequate}; k = {k_after['value']:.3f} N/mm, 95 % interval "
    f"[{k_after['ci95'][0]:.3f}, {k_after['ci95'][1]:.3f}] (k_c = {args.k_c:g}); named effects "
    f"still significant: {still or 'none'}"
)

# %% [markdown]
# ## 5b. The same term from the command line
# `fabricsurf fit DATA --effects my_effects.py --terms fibre_stretch,shear,shear_tension_plus`,
# run in-process: it loads the module for the one command, fits from the default moduli (a
# scan by decades first) and writes fit.json with the moduli, their 95 % intervals and the
# comparison figures. Its interval of k is wider than the search's: besides the noise's part it
# holds the mesh part (one run at h/2) and the model-form part, the spread of k between the
# three load steps refitted alone (docs/uncertainty.md).

# %%
status = cli(
    [
        "fit",
        str(data),
        "--effects",
        str(module),
        "--terms",
        ",".join(BASE + [new]),
        "--h",
        str(H),
        "--out",
        str(out / "fit_cli"),
    ]
)
require(status == 0, f"fabricsurf fit exited {status}")
fit_cli = json.loads((out / "fit_cli" / "fit.json").read_text()) if comm.rank == 0 else None
fit_cli = comm.bcast(fit_cli)
k_cli = fit_cli["moduli"][f"{new}.k"]
say(
    f"fabricsurf fit --effects: k = {k_cli['value']:.3f} N/mm, 95 % interval "
    f"[{k_cli['ci95'][0]:.3f}, {k_cli['ci95'][1]:.3f}]; misfit {fit_cli['misfit']['combined']:.3f}"
)

# %% [markdown]
# ## 6. Before and after: the force curve and the field errors
# From the left: the force error of the baseline, of the named diagnosis's final model and of
# the model with the new term, in units of the force noise (grey: ±2σ; crosses: the noise-free
# force the data were made from, i.e. minus the noise drawn); the misfit of each step; the
# displacement error at each measured point at the last step, for the named model and for the
# model with the new term, in units of the noise (√2 σ_u for the length of a 2-component error,
# so pure noise has RMS 1). The named models' errors grow with the load, as the coupling's
# energy does (γ² times the fibre stretches); the new model's stay at the noise level.

# %%


def figure(path) -> None:
    """The four panels above, written to ``path`` (rank 0)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = [
        ("fibre_stretch+shear", named.base_fit, "C0s--"),
        ("+".join(named.terms) + " (named)", named.final_fit, "C1^-."),
        ("+".join(after.terms) + " (new term)", after.final_fit, "C2o-"),
    ]
    fig, ax = plt.subplots(1, 4, figsize=(19, 4.2), width_ratios=[1, 1, 1.1, 1.1])
    s_F, s_u = exp.force_noise_std, exp.noise_std * np.sqrt(2)  # |u error|: two components
    ax[0].plot(exp.path, (clean_force - exp.force) / s_F, "kx", ms=8, label="noise-free data")
    for label, res, style in models:
        err = (res.prediction[0].force - exp.force) / s_F  # one prediction per experiment
        ax[0].plot(exp.path, err, style, label=label)
        steps = res.misfit["experiments"][0]["per_step"]
        ax[1].plot(
            exp.path,
            [q["combined"] for q in steps],
            style,
            label=f"{label}: {res.misfit['combined']:.2f}",
        )
    ax[0].axhspan(-2, 2, color="0.9", zorder=0)
    ax[0].set(xlabel="grip displacement (mm)", ylabel="(model − data) / σ_F", title="force")
    ax[0].legend(fontsize=7)
    ax[1].axhline(1.0, color="k", lw=0.8)
    ax[1].set(
        xlabel="grip displacement (mm)",
        ylabel="misfit (1 = noise level)",
        title="misfit per step (overall in the legend)",
        ylim=(0, None),
    )
    ax[1].legend(fontsize=7)
    rows = exp.step_rows(exp.steps[-1])
    X = exp.X[rows]
    err = [res.misfit["experiments"][0]["row_error"][rows] / s_u for _, res, _ in models[1:]]
    vmax = max(float(np.max(e)) for e in err)
    for a, (label, _, _), e in zip(ax[2:], models[1:], err):
        sc = a.scatter(X[:, 0], X[:, 1], c=e, s=60, cmap="viridis", vmin=0, vmax=vmax)
        a.set(
            xlim=(0, L),
            ylim=(0, W),
            aspect="equal",
            xlabel="x (mm)",
            title=f"{label}\ndisplacement error at {exp.path[-1]:g} mm: RMS "
            f"{np.sqrt(np.mean(e**2)):.2f}",
        )
        a.title.set_fontsize(8)
    fig.colorbar(sc, ax=ax[2:], shrink=0.8, label="|u error| / (√2 σ_u)  (1 = noise)")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


on_rank0(comm, figure, out / "before_after.png")

# %% [markdown]
# ## 7. Other noise draws (full mode)
# One draw of the noise could be lucky. The full mode repeats the diagnosis and the search on
# four more draws of the same noise over the same noise-free data (nothing is written for them)
# and counts how often the pipeline searched, how often it named γ²((λ−1)+(μ−1)) first and
# alone, and how often the hidden k_c lies in its interval.

# %%
draws = []
for seed in [] if args.quick else range(args.seed + 1, args.seed + 5):
    e = sy.noisy_copy(clean, args.noise, 0.02, seed)
    with detail():
        d = fsf.diagnose(e, BASE, h=H, confirm=2, max_effects=1, comm=comm)
        rec = search_beyond(d, e, comm=comm)
    f = rec["found"][0] if rec["found"] else None
    draws.append(
        {
            "seed": seed,
            "named": d.verdict_text(),
            "adequate": d.adequate,
            "searched": rec["searched"],
            "feature": f and f["feature"],
            "alone": bool(f) and not f["indistinguishable_from"],
            "k": f and f["modulus"]["value"],
            "ci95": f and f["modulus"]["ci95"],
            "k_in_interval": bool(f)
            and f["modulus"]["ci95"][0] <= args.k_c <= f["modulus"]["ci95"][1],
            "misfit": [f["misfit_before"], f["refit_misfit"]] if f else d.path[-1]["misfit"],
        }
    )
    say(f"noise seed {seed}: named {d.verdict_text()}, adequate {d.adequate}; {rec['outcome']}")
hits = sum(q["feature"] == "shear_tension_plus" and q["alone"] for q in draws)
covered = sum(q["feature"] == "shear_tension_plus" and q["k_in_interval"] for q in draws)

# %% [markdown]
# ## 8. Account and summary

# %%
lo, hi = found["modulus"]["ci95"]
before_misfit, after_misfit = named.final_fit.misfit["combined"], after.final_fit.misfit["combined"]
factor = before_misfit / after_misfit
say("\n=== account ===")
say(
    f"named diagnosis: {named.outcome()} (baseline misfit {named.path[0]['misfit']:.3f} → "
    f"{before_misfit:.3f}; 1 = noise level)"
)
say(f"beyond the vocabulary: {beyond['outcome']}")
say(
    f"  {found['energy']}: k = {found['modulus']['value']:.3f} N/mm, 95 % interval "
    f"[{lo:.3f}, {hi:.3f}] (hidden k_c = {args.k_c:g}); Wald p {found['wald_p']:.2g} against "
    f"{found['wald_p_needed']:.2g} needed; {len(beyond['library'])} features searched"
)
say(
    f"with {new} from {module.name}: {after.outcome()}; misfit {after_misfit:.3f} "
    f"(fell {factor:.2f}×), k = {fitted[new]['k']:.3f} N/mm"
)
if draws:
    say(
        f"other noise draws: γ²((λ−1)+(μ−1)) named first and alone in {hits} of {len(draws)}, "
        f"k_c in its interval in {covered}"
    )
summary = {
    "truth": TRUTH,
    "noise": [args.noise, 0.02],
    "h": H,
    "h_data": H_DATA,
    "quick": args.quick,
    "named": {
        "outcome": named.outcome(),
        "verdict": named.verdict_text(),
        "terms": named.terms,
        "adequate": named.adequate,
        "baseline_misfit": named.path[0]["misfit"],
        "misfit": before_misfit,
        "chi2_h": named.discretisation_chi2,
    },
    "beyond": {
        "outcome": beyond["outcome"],
        "feature": found["feature"],
        "proportional_to": found["proportional_to"],
        "energy": found["energy"],
        "share_of_excess": found["share_of_excess"],
        "modulus": found["modulus"],
        "k_in_interval": bool(lo <= args.k_c <= hi),
        "wald_p": found["wald_p"],
        "wald_p_needed": found["wald_p_needed"],
        "indistinguishable_from": found["indistinguishable_from"],
        "where": found["where"][:3],
        "misfit_before": found["misfit_before"],
        "refit_misfit": found["refit_misfit"],
        "family_size": beyond["multiple_testing"]["family_size"],
        "seconds": beyond["seconds"],
    },
    "module": {
        "file": module.name,
        "loaded": [new],
        "registered_from": origin,
        "linear": origin == str(module),  # register_effect registers only after check_linear
        "nonlinear_variant_refused": bool(refused and "not linear" in refused),
    },
    "with_new_term": {
        "outcome": after.outcome(),
        "terms": after.terms,
        "adequate": after.adequate,
        "verdict": after.verdict,
        "misfit": after_misfit,
        "params": fitted,
        "k": k_after,
        "still_significant": still,
        "chi2_h": after.discretisation_chi2,
    },
    "fit_cli": {
        "k": k_cli,
        "misfit": fit_cli["misfit"]["combined"],
        "params": fit_cli["params"],
        "k_in_interval": bool(k_cli["ci95"][0] <= args.k_c <= k_cli["ci95"][1]),
    },
    "other_draws": {"runs": draws, "named_alone": hits, "k_c_in_interval": covered},
    "misfit_factor": factor,
    "seconds": time.perf_counter() - t_start,
}
write_json(comm, out / "summary.json", summary)
on_rank0(comm, (out / "search_beyond.json").write_text, json.dumps(beyond, indent=1))

# %% [markdown]
# ## Checks
# `CHECKS` is the summary's contract, also read by tests/test_demos.py:
#
# * the named diagnosis is not adequate: the vocabulary alone cannot explain a coupling it does
#   not have (the benchmark's pipeline searched in 12 of 12 such data sets at this noise);
# * the search's first feature is `shear_tension_plus`, ∝ γ²((λ−1)+(μ−1)), alone (no feature
#   the data cannot tell from it): the form that made the data; it removes at least half of the
#   excess misfit (a feature that takes up only a part names a part of what is missing);
# * its 95 % interval holds the hidden k_c (6 of 6 data sets in the benchmark);
# * the written module loads (registered from its file, which the linearity check must pass
#   first), and the k² variant is refused by that check: the check is real;
# * with the new term the model is adequate and no named effect is significant on top of it
#   (the stand-in yarn_slip is not needed), the misfit is at most 1.1 noise levels and it fell
#   by at least 1.4× from the named model's (measured 1.62×: 1.466 → 0.907; the excess
#   misfit² − 1 goes from 1.15 to below 0).

# %%
CHECKS = {
    "named/adequate": False,
    "beyond/feature": "shear_tension_plus",
    "beyond/proportional_to": "γ²((λ−1)+(μ−1))",
    "beyond/indistinguishable_from": [],
    "beyond/k_in_interval": True,
    "beyond/share_of_excess": (0.5, None),
    "module/loaded": ["shear_tension_plus"],
    "module/linear": True,
    "module/nonlinear_variant_refused": True,
    "with_new_term/adequate": True,
    "with_new_term/verdict": None,
    "with_new_term/still_significant": [],
    "with_new_term/misfit": (0.0, 1.1),
    "misfit_factor": (1.4, None),
}
verify(summary, CHECKS)
require(after_misfit < before_misfit, (after_misfit, before_misfit))
if not args.quick:  # the benchmark: 12 of 12 at this noise; here one miss in four is allowed
    require(hits >= 3 and covered >= hits, (hits, covered, len(draws)))
say(f"figure, data, module and summary in {out} ({summary['seconds']:.0f} s)")
