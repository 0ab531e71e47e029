"""Figures of model vs measurement (matplotlib, Agg; call on rank 0 only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.inverse.data import Experiment


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def error_map(exp: Experiment, preds: list[tuple[str, object]], steps: list[int],
              path: Path) -> None:
    """|u_model − u_meas| (mm) over the specimen: one row per model, one column per step."""
    plt = _plt()
    errs = [np.linalg.norm(p.u - exp.u[:, :2], axis=1) for _, p in preds]
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


def force_curves(exp: Experiment, preds: list[tuple[str, object]], path: Path) -> None:
    """Measured and model grip force against the grip displacement."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.plot(exp.displacement, exp.force, "ko", label="measured")
    for label, p in preds:
        ax.plot(exp.displacement, p.force, "-", label=label)
    ax.set(xlabel="grip displacement (mm)", ylabel="force (N)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def error_vs_step(exp: Experiment, misfits: list[tuple[str, dict]], path: Path,
                  noise: float | None = None) -> None:
    """Field RMS error (mm) and |force error| (N) per step."""
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
    for label, m in misfits:
        ax[0].semilogy(exp.steps, [s["field_rms"] for s in m["per_step"]], "o-", label=label)
        ax[1].semilogy(exp.steps, [abs(s["force_error"]) for s in m["per_step"]], "o-",
                       label=label)
    if noise:
        ax[0].axhline(noise, color="k", ls="--", label="noise_std")
    ax[0].set(xlabel="step", ylabel="field RMS error (mm)")
    ax[1].set(xlabel="step", ylabel="|force error| (N)")
    ax[0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def default_steps(exp: Experiment) -> list[int]:
    """The middle and the last step."""
    s = [int(exp.steps[len(exp.steps) // 2]), int(exp.steps[-1])]
    return sorted(set(s))
