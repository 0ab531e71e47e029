"""Figures of model vs measurement (matplotlib, Agg; call on rank 0 only).

Every function takes one experiment and a list of (label, prediction) pairs, and draws only what
the experiment measured (field, force or both).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.experiment import Experiment


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def error_map(exp: Experiment, preds: list[tuple[str, object]], steps: list[int],
              path: Path) -> None:
    """|u_model − u_meas| (mm) over the specimen: one row per model, one column per step."""
    plt = _plt()
    errs = [np.linalg.norm(p.u - exp.u[:, : p.u.shape[1]], axis=1) for _, p in preds]
    vmax = max(float(np.nanmax(e)) for e in errs) or 1.0
    fig, axes = plt.subplots(len(preds), len(steps), squeeze=False,
                             figsize=(4.2 * len(steps), 2.6 * len(preds) + 0.6))
    for i, ((label, _), e) in enumerate(zip(preds, errs)):
        for j, s in enumerate(steps):
            rows = exp.step_rows(s)
            ax = axes[i, j]
            sc = ax.scatter(exp.X[rows, 0], exp.X[rows, 1], c=e[rows], s=18, cmap="viridis",
                            vmin=0.0, vmax=vmax)
            ax.set(xlim=(0, exp.length), ylim=(0, exp.width), aspect="equal",
                   xlabel="X (mm)", ylabel="Y (mm)")
            ax.set_title(f"{label}: step {s}", fontsize=8)
    fig.colorbar(sc, ax=axes, label="|u_model − u_meas| (mm)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def field_band(exp: Experiment, half: np.ndarray, path: Path) -> None:
    """The 95 % half-widths of the predicted displacements at the measurement points of the
    last step, as the norm |(h_x, h_y[, h_z])| (mm)."""
    plt = _plt()
    rows = exp.step_rows(int(exp.steps[-1]))
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    sc = ax.scatter(exp.X[rows, 0], exp.X[rows, 1], c=np.linalg.norm(half[rows], axis=1), s=18,
                    cmap="magma")
    ax.set(xlim=(0, exp.length), ylim=(0, exp.width), aspect="equal", xlabel="X (mm)",
           ylabel="Y (mm)", title=f"{exp.name}: 95 % band of u, step {int(exp.steps[-1])}")
    fig.colorbar(sc, ax=ax, label="half-width (mm)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def force_curves(exp: Experiment, preds: list[tuple[str, object]], path: Path) -> None:
    """Measured and model reaction against the load path."""
    plt = _plt()
    plugin = get_test(exp.test)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.plot(exp.path, exp.force, "ko", ms=4, label="measured")
    for label, p in preds:
        ax.plot(exp.path, p.force, "-", label=label)
    ax.set(xlabel=plugin.path_label, ylabel=plugin.reaction_label, title=exp.name)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def force_band(band: dict, path: Path, title: str, measured: tuple | None = None,
               xlabel: str = "grip displacement (mm)") -> None:
    """A predicted force curve with its 95 % band (:func:`~fabricsurf.inverse.fitting.band.
    force_band`), and measured points ``(load, force)`` when given; the title says whether the
    linearisation held."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.fill_between(band["load"], band["lower"], band["upper"], color="C0", alpha=0.3,
                    label="95 % band")
    ax.plot(band["load"], band["force"], "C0-", label="prediction")
    if measured is not None:
        ax.plot(*measured, "ko", ms=3, label="measured")
    note = {True: "linear band checked", False: "band unreliable (nonlinear)",
            None: "linearity not checked"}[band["reliable"]]
    ax.set(xlabel=xlabel, ylabel="force (N)", title=f"{title}\n{note}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def error_vs_step(exp: Experiment, misfits: list[tuple[str, dict]], path: Path) -> None:
    """Field RMS error (mm) and |force error| (N) per step, with the noise levels."""
    plt = _plt()
    panels = [k for k, has in (("field", exp.has_field), ("force", exp.has_force)) if has]
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 3.8), squeeze=False)
    for ax, kind in zip(axes[0], panels):
        for label, m in misfits:
            if kind == "field":
                y = [s["field_rms"] or np.nan for s in m["per_step"]]
            else:
                y = [abs(s["force_error"]) for s in m["per_step"]]
            ax.semilogy(exp.steps, y, "o-", label=label)
        noise = exp.noise_std if kind == "field" else exp.force_noise_std
        if noise:
            ax.axhline(noise, color="k", ls="--", label="noise std")
        ax.set(xlabel="step", ylabel="field RMS error (mm)" if kind == "field"
               else "|force error| (N)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def misfit_path(path_rows: list[dict], out: Path) -> None:
    """The combined misfit after each step of a stepwise diagnosis (noise level = 1)."""
    plt = _plt()
    labels = ["+".join(path_rows[0]["terms"])] + ["+ " + r["added"] for r in path_rows[1:]]
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    ax.plot(range(len(path_rows)), [r["misfit"] for r in path_rows], "o-")
    ax.axhline(1.0, color="k", ls="--", label="noise level")
    ax.set_xticks(range(len(path_rows)), labels, rotation=15, fontsize=8)
    ax.set(ylabel="combined misfit (noise units)", title="error falling step by step")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def default_steps(exp: Experiment) -> list[int]:
    """The middle and the last step."""
    s = [int(exp.steps[len(exp.steps) // 2]), int(exp.steps[-1])]
    return sorted(set(s))
