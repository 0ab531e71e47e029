"""What demos/demo_bending.py computes besides the diagnosis: the 0° strip against the heavy
elastica under refinement, the textile engineer's start for k_b (Peirce's bending length from
the measured profile), and the figures (rank 0)."""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path

import numpy as np

from fabricsurf.experiments.cantilever import CantileverTest, rigidity_uNm, weight_per_area
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.verification.elastica import peirce_bending_length, solve_elastica


def elastica_study(model: list, length: float, width: float, rho: float, c: float,
                   cells: tuple[int, ...]) -> tuple[dict, list[dict], list[float]]:
    """The 0° strip on meshes of ``cells`` elements along it against the heavy elastica of
    bending length ``c``: max |u_FE − u_elastica| over 8 centre-line points, and the observed
    rates between successive meshes. Returns (elastica tip, rows per mesh, rates)."""
    el = solve_elastica(length, c)
    X = np.linspace(length / 8, length, 8)
    ref = el.displacement(X)
    setup = sy.template(length, width, [1.0], np.zeros((0, 2)), angles=(0.0, 90.0),
                        test="cantilever", options={"areal_density_g_m2": rho}).setup
    study = []
    for n in cells:
        strip = CantileverTest(setup, model, length / n)
        t0 = time.perf_counter()
        strip.run(1.0, steps=4)
        u = strip.displacement_at(np.column_stack([X, np.full(8, width / 2)]))
        err = float(np.max(np.hypot(u[:, 0] - ref[:, 0], u[:, 2] - ref[:, 1])))
        study.append({"n": n, "h": length / n, "error_mm": err, "tip_fe": strip.tip_deflection(),
                      "seconds": time.perf_counter() - t0})
    rates = [math.log2(a["error_mm"] / b["error_mm"]) for a, b in itertools.pairwise(study)]
    tip = {"tip_deflection": el.tip_deflection, "tip_angle_deg": math.degrees(el.tip_angle)}
    return tip, study, rates


def peirce_rigidity(exp, rho: float) -> float:
    """ρ_A g c³ (N·mm) with Peirce's c from the mean chord angle of the outermost points at
    the last load factor (the overhang l is their reference x)."""
    rows = exp.step_rows(exp.steps[-1])
    far = rows[np.isclose(exp.X[rows, 0], exp.X[rows, 0].max())]
    x, u = exp.X[far, 0].mean(), exp.u[far].mean(axis=0)
    c = peirce_bending_length(x, math.atan2(-u[2], x + u[0]))
    return exp.path[-1] * weight_per_area(rho) * c**3


def figures(out: Path, exps: dict, preds: dict, noise: float) -> None:
    """shapes_3d.png (measured points and model surfaces at the full weight, per model of
    ``preds``) and residuals_uz.png (model − measured u_z along the strips)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 9))
    for row, (name, exp) in enumerate(exps.items()):
        rows = exp.step_rows(exp.steps[-1])
        for col, (label, pr) in enumerate(preds.items()):
            ax = fig.add_subplot(2, 2, 2 * row + col + 1, projection="3d")
            P = exp.X[rows] + exp.u[rows, :2]
            ax.scatter(P[:, 0], P[:, 1], exp.u[rows, 2], c="k", s=8, label="measured")
            Um = pr[row].u[rows]
            M = exp.X[rows] + Um[:, :2]
            ax.plot_trisurf(M[:, 0], M[:, 1], Um[:, 2], alpha=0.5, color="tab:orange")
            err = np.sqrt(np.mean(np.sum((Um - exp.u[rows]) ** 2, axis=1)))
            ax.set(title=f"{name}, {label}: RMS error {err:.3f} mm", xlabel="x (mm)",
                   ylabel="y (mm)", zlabel="z (mm)")
    fig.tight_layout()
    fig.savefig(out / "shapes_3d.png", dpi=110)
    plt.close(fig)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, (row, (name, exp)) in zip(axes, enumerate(exps.items())):
        rows = exp.step_rows(exp.steps[-1])
        for (label, pr), mk in zip(preds.items(), ("x", "o")):
            ax.plot(exp.X[rows, 0], pr[row].u[rows, 2] - exp.u[rows, 2], mk, ms=4, label=label)
        ax.axhspan(-2 * noise, 2 * noise, color="0.85", label="±2 noise std")
        ax.set(title=f"{name}, full weight", xlabel="x (mm)", ylabel="model − measured u_z (mm)")
        ax.legend()
    fig.tight_layout()
    fig.savefig(out / "residuals_uz.png", dpi=110)
    plt.close(fig)


def strip_data(comm, out: Path, strips: dict, model: list, size: tuple[float, float],
               path: list[float], rho: float, h: float, noise: float) -> dict:
    """The measured strips: for each name → fibre angles of ``strips``, 10 × 5 points of the
    continuum ``model`` on a mesh ``h`` (u_x, u_y, u_z at every load factor of ``path``), plus
    noise (fixed draw per strip, the same on every rank), written as a measurement directory
    under ``out/data`` and read back."""
    from fabricsurf.inverse.contract.data import load_experiment, write_experiment

    exps = {}
    for i, (name, angles) in enumerate(strips.items()):
        pts = sy.grid_points(*size, 10, 5)
        exp = sy.template(*size, path, pts, angles=angles, name=name, test="cantilever",
                          options={"areal_density_g_m2": rho}, force=False)
        sy.continuum_data(exp, model, h=h)  # collective
        sy.add_noise(exp, noise, 0.0, seed=31 + i)
        exp.source = {"note": "continuum normal_bending + twist on a fine mesh, plus noise"}
        if comm.rank == 0:
            write_experiment(out / "data" / name, exp, overwrite=True)
        comm.barrier()
        exps[name] = load_experiment(out / "data" / name)
    return exps


def write_strips(out: Path, exps: dict, model: list, h: float, steps: int) -> None:
    """``strip_*.xdmf``: ``model`` along each strip's ramp with its kinematic fields."""
    from fabricsurf.discretise.output import FieldWriter

    for name, exp in exps.items():
        strip = CantileverTest(exp.setup, model, h)
        writer = FieldWriter(out / f"{name}.xdmf", strip.problem.u, strip.problem.energy.kin)
        strip.run(1.0, steps=steps, on_step=lambda k, t, w=writer: w.write(t))
        writer.close()


def fit_each_alone(exps: dict, model_for, h: float, rho: float) -> dict:
    """The baseline fitted to each strip alone, k_b free from Peirce's estimate
    (``model_for(k_b)`` the term list): misfit, k_b, adequacy, forward runs per strip."""
    from fabricsurf.inverse.fitting import significance as sg
    from fabricsurf.inverse.fitting.fit import fit
    from fabricsurf.inverse.fitting.forward import ForwardModel

    alone = {}
    for name, exp in exps.items():
        k0 = peirce_rigidity(exp, rho)
        fm = ForwardModel(exp, model_for(k0), h=h)
        res = fit(fm, [fm.names.index("normal_bending.k_b")], verbose=False, scale_start=False)
        alone[name] = {"peirce_rigidity": k0, "misfit": res.misfit["combined"],
                       "k_b": res.params()["normal_bending"]["k_b"],
                       "adequate": sg.adequate(res.chi2, res.misfit["n"], 1),
                       "forward_runs": res.forward_runs}
    return alone


def report_diagnosis(d, say, seconds: float) -> tuple[dict, dict]:
    """Print the diagnosis of the two strips (verdict, per-strip misfits, ranking, fitted
    moduli against the truth); return the fitted (value, std) by "term.param" and the
    per-experiment misfits of the baseline and final fits."""
    base, final = d.base_fit, d.final_fit
    fitted = {n: (float(v), float(s)) for n, v, s in zip(final.names, final.values, final.std)}
    per = {"baseline": {e["experiment"]: e["combined"] for e in base.misfit["experiments"]},
           "final": {e["experiment"]: e["combined"] for e in final.misfit["experiments"]}}
    say(f"verdict: {d.verdict}; adequate: {d.adequate}; misfit {base.misfit['combined']:.3f} -> "
        f"{final.misfit['combined']:.3f} ({seconds:.0f} s, "
        f"{base.forward_runs + final.forward_runs} forward runs in the two fits)")
    for name in per["baseline"]:
        say(f"  {name}: misfit {per['baseline'][name]:.3f} -> {per['final'][name]:.3f}")
    for r in d.ranking:
        say(f"  {r['effect']:15s} score {r['score']:10.1f} refit misfit {r['refit_misfit']}")
    kb, kt = fitted["normal_bending.k_b"], fitted.get("twist.k_t", (0.0, 0.0))
    say(f"k_b = {kb[0]:.5f} ± {kb[1]:.5f} N·mm (truth 0.02; {rigidity_uNm(kb[0]):.2f} µN·m), "
        f"k_t = {kt[0]:.5f} ± {kt[1]:.5f} N·mm (truth 0.01)")
    return fitted, per
