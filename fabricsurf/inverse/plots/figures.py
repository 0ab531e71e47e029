"""Figures of model vs measurement (matplotlib, Agg; call on rank 0 only).

Every function takes one experiment and a list of (label, prediction) pairs, and draws only what
the experiment measured (field, force or both). A field of more than :data:`SCATTER_MAX` points
per step (a DIC export: 10⁴–10⁵ per image) is drawn as an image of its values averaged over bins
of the specimen, with the points' density (points per bin) in a panel of its own: a scatter of
so many points is unreadable and slow to draw. The per-point values stay in the per-point CSV.
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


SCATTER_MAX = 4000
"""Points per step up to which a field is drawn as a scatter; above, as a binned image."""

POINTS_PER_BIN = 4
"""The bins of an image hold about this many points each on average (a smooth mean)."""

MAX_BINS = 240
"""The most bins along the specimen's length (finer than a figure shows)."""


def bins(exp: Experiment, n: int) -> tuple[int, int]:
    """(bins along X, along Y) for ``n`` points over the specimen: about
    :data:`POINTS_PER_BIN` points per bin, square bins, at most :data:`MAX_BINS` along X."""
    aspect = exp.length / max(exp.width, 1e-300)
    nx = int(np.clip(np.sqrt(n / POINTS_PER_BIN * aspect), 2, MAX_BINS))
    return nx, max(2, round(nx / aspect))


def binned(
    exp: Experiment, X: np.ndarray, values: np.ndarray, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """(mean of ``values`` per bin, points per bin), each (ny × nx), NaN mean in an empty bin
    or one whose points have no finite value; O(n) (bincount)."""
    nx, ny = shape
    ix = np.clip((X[:, 0] / exp.length * nx).astype(int), 0, nx - 1)
    iy = np.clip((X[:, 1] / exp.width * ny).astype(int), 0, ny - 1)
    k = iy * nx + ix
    ok = np.isfinite(values)
    total = np.bincount(k[ok], weights=values[ok], minlength=nx * ny)
    count = np.bincount(k[ok], minlength=nx * ny)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return mean.reshape(ny, nx), np.bincount(k, minlength=nx * ny).reshape(ny, nx)


def _field(ax, exp: Experiment, rows: np.ndarray, values: np.ndarray, shape, **style):
    """The values at the points ``rows`` on ``ax``: a scatter, or the binned image (module
    docstring); returns the mappable."""
    ax.set(
        xlim=(0, exp.length), ylim=(0, exp.width), aspect="equal", xlabel="X (mm)", ylabel="Y (mm)"
    )
    if shape is None:
        return ax.scatter(exp.X[rows, 0], exp.X[rows, 1], c=values, s=18, **style)
    mean, _ = binned(exp, exp.X[rows], values, shape)
    return ax.imshow(
        mean, origin="lower", extent=(0, exp.length, 0, exp.width), interpolation="nearest", **style
    )


def _density(fig, ax, exp: Experiment, rows: np.ndarray, shape, step: int) -> None:
    """Points per bin of one step (the data's density; white where there are none)."""
    _, count = binned(exp, exp.X[rows], np.zeros(len(rows)), shape)
    im = ax.imshow(
        np.where(count > 0, count, np.nan),
        origin="lower",
        cmap="Greys",
        extent=(0, exp.length, 0, exp.width),
        interpolation="nearest",
    )
    ax.set(aspect="equal", xlabel="X (mm)", ylabel="Y (mm)")
    ax.set_title(
        f"points per bin, step {step} ({len(rows)} points, {shape[0]}×{shape[1]} bins)", fontsize=8
    )
    fig.colorbar(im, ax=ax, label="points per bin", shrink=0.8)


def _shape(exp: Experiment, steps: list[int]):
    """The bins of the steps' images, or None when every step is small enough to scatter."""
    n = max(len(exp.step_rows(s)) for s in steps)
    return None if n <= SCATTER_MAX else bins(exp, n)


def error_map(
    exp: Experiment, preds: list[tuple[str, object]], steps: list[int], path: Path
) -> None:
    """|u_model − u_meas| (mm) over the specimen: one row per model, one column per step (a
    binned image and the points' density for large fields: module docstring)."""
    plt = _plt()
    errs = [np.linalg.norm(p.u - exp.u[:, : p.u.shape[1]], axis=1) for _, p in preds]
    vmax = max(float(np.nanmax(e)) for e in errs) or 1.0
    shape = _shape(exp, steps)
    cols = len(steps) + (shape is not None)
    fig, axes = plt.subplots(
        len(preds), cols, squeeze=False, figsize=(4.2 * cols, 2.6 * len(preds) + 0.6)
    )
    for i, ((label, _), e) in enumerate(zip(preds, errs)):
        for j, s in enumerate(steps):
            rows = exp.step_rows(s)
            sc = _field(axes[i, j], exp, rows, e[rows], shape, cmap="viridis", vmin=0.0, vmax=vmax)
            axes[i, j].set_title(
                f"{label}: step {s}" + (" (bin means)" if shape else ""), fontsize=8
            )
    fig.colorbar(sc, ax=axes[:, : len(steps)], label="|u_model − u_meas| (mm)")
    if shape is not None:
        _density(fig, axes[0, -1], exp, exp.step_rows(steps[-1]), shape, steps[-1])
        for ax in axes[1:, -1]:
            ax.axis("off")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def field_band(exp: Experiment, half: np.ndarray, path: Path) -> None:
    """The 95 % half-widths of the predicted displacements at the measurement points of the
    last step, as the norm |(h_x, h_y[, h_z])| (mm); binned for large fields."""
    plt = _plt()
    step = int(exp.steps[-1])
    rows = exp.step_rows(step)
    shape = _shape(exp, [step])
    fig, axes = plt.subplots(
        1, 1 + (shape is not None), squeeze=False, figsize=(5.5 * (1 + (shape is not None)), 3.6)
    )
    sc = _field(axes[0, 0], exp, rows, np.linalg.norm(half[rows], axis=1), shape, cmap="magma")
    axes[0, 0].set_title(f"{exp.name}: 95 % band of u, step {step}", fontsize=9)
    fig.colorbar(sc, ax=axes[0, 0], label="half-width (mm)")
    if shape is not None:
        _density(fig, axes[0, 1], exp, rows, shape, step)
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


def force_band(
    band: dict,
    path: Path,
    title: str,
    measured: tuple | None = None,
    xlabel: str = "grip displacement (mm)",
) -> None:
    """A predicted force curve with its 95 % band (:func:`~fabricsurf.inverse.fitting.band.
    force_band`), and measured points ``(load, force)`` when given; the title says whether the
    linearisation held."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.fill_between(
        band["load"], band["lower"], band["upper"], color="C0", alpha=0.3, label="95 % band"
    )
    ax.plot(band["load"], band["force"], "C0-", label="prediction")
    if measured is not None:
        ax.plot(*measured, "ko", ms=3, label="measured")
    note = {
        True: "linear band checked",
        False: "band unreliable (nonlinear)",
        None: "linearity not checked",
    }[band["reliable"]]
    ax.set(xlabel=xlabel, ylabel="force (N)", title=f"{title}\n{note}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def error_vs_step(exp: Experiment, misfits: list[tuple[str, dict]], path: Path) -> None:
    """Field RMS error (mm), |force error| (N) and shear RMS error (deg) per step, with the
    noise levels."""
    plt = _plt()
    panels = [
        k
        for k, has in (("field", exp.has_field), ("force", exp.has_force), ("shear", exp.has_shear))
        if has
    ]
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 3.8), squeeze=False)
    for ax, kind in zip(axes[0], panels):
        for label, m in misfits:
            if kind == "force":
                y = [abs(s["force_error"]) or np.nan for s in m["per_step"]]  # log axis
            else:
                y = [
                    s[f"{kind}_rms" + ("_deg" if kind == "shear" else "")] or np.nan
                    for s in m["per_step"]
                ]
            ax.semilogy(exp.steps, y, "o-", label=label)
        noise = {
            "field": exp.noise_std,
            "force": exp.force_noise_std,
            "shear": exp.shear_noise_deg,
        }[kind]
        if noise:
            ax.axhline(noise, color="k", ls="--", label="noise std")
        ax.set(
            xlabel="step",
            ylabel={
                "field": "field RMS error (mm)",
                "force": "|force error| (N)",
                "shear": "shear RMS error (deg)",
            }[kind],
        )
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


def difference_map(
    maps: list[tuple[str, Experiment, np.ndarray]], effects: list[str], path: Path
) -> None:
    """|u_a − u_b|/s_u of two tied models' predictions at the last step of each experiment of
    ``maps`` (title, experiment, value per field row): where the data cannot separate them and
    where the suggested experiment would (:mod:`~fabricsurf.inverse.diagnosis.discrimination`).
    Experiments without a field at their last step (force only) have nothing to map and are
    left out; with none left, no figure is written."""
    maps = [m for m in maps if len(m[1].step_rows(m[1].steps[-1]))]  # a force-only test: none
    if not maps:
        return
    plt = _plt()
    fig, axes = plt.subplots(
        1, max(len(maps), 1), squeeze=False, figsize=(4.8 * max(len(maps), 1), 3.4)
    )
    for ax, (title, exp, values) in zip(axes[0], maps):
        rows = exp.step_rows(exp.steps[-1])
        sc = _field(
            ax, exp, rows, values[rows], _shape(exp, [int(exp.steps[-1])]), cmap="magma", vmin=0.0
        )
        ax.set_title(f"{title}\nlast step (max {np.nanmax(values[rows]):.3g})", fontsize=8)
        fig.colorbar(sc, ax=ax, shrink=0.8, label=f"|u({effects[0]}) − u({effects[1]})| / noise")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
