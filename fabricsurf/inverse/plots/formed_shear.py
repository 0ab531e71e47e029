"""Measured shear angles of a formed part against the model: the per-point CSV and the figure
(written by outputs.py next to the field data's)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.plots.figures import _plt


def per_point_csv(path: Path, exp: Experiment, pred) -> None:
    """One row per measured shear angle: step, the point on the specimen (mm), measured and
    model shear angles and their difference (deg; NaN: the point lies outside the mesh)."""
    rows = np.column_stack(
        [exp.shear_step, exp.shear_X, exp.shear, pred.shear, pred.shear - exp.shear]
    )
    np.savetxt(
        path,
        rows,
        delimiter=",",
        fmt=["%d"] + ["%.10g"] * 5,
        comments="",
        header="step,X_mm,Y_mm,shear_meas_deg,shear_model_deg,error_deg",
    )


def shear_figure(exp: Experiment, preds: list[tuple[str, object]], path: Path) -> None:
    """Model against measured shear angle at every point (the diagonal: agreement), one colour
    per model, with the noise band when the data give it."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(4.8, 4.5))
    lo, hi = float(np.min(exp.shear)), float(np.max(exp.shear))
    pad = 0.05 * max(hi - lo, 1.0)
    line = np.array([lo - pad, hi + pad])
    ax.plot(line, line, "k-", lw=0.8, label="model = measured")
    if exp.shear_noise_deg:
        ax.fill_between(
            line,
            line - 2 * exp.shear_noise_deg,
            line + 2 * exp.shear_noise_deg,
            color="0.85",
            label="±2 noise std",
        )
    for label, pred in preds:
        ax.plot(exp.shear, pred.shear, "o", ms=3, label=label)
    ax.set(
        xlabel="measured shear angle (deg)",
        ylabel="model shear angle (deg)",
        title=f"{exp.name}: shear at {len(exp.shear)} points",
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
