"""The figure of where the excess misfit sits: the mean z² per component of the final model's
field rows by distance from the grips and zone boundaries and by the model's shear angle
(:func:`~fabricsurf.inverse.diagnosis.excess.excess_location`; call on rank 0 only)."""

from __future__ import annotations

from pathlib import Path

from fabricsurf.inverse.diagnosis.excess_text import WORDS
from fabricsurf.inverse.plots.figures import _plt


def _labels(bins: list[dict]) -> list[str]:
    return [f"≥ {b['from']:g}" if b["to"] is None else f"{b['from']:g}–{b['to']:g}" for b in bins]


def excess_figure(rec: dict, out: Path) -> None:
    """Two bar panels, mean z² per band (1 = the noise level), each bar labelled with its share
    of the rows and of the excess."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 3.8))
    unit = "yarn spacings" if rec.get("yarn_spacing_mm") else "mesh sizes h"
    for ax, key, xlabel in (
        (axes[0], "by_distance", f"distance from grips and zone boundaries ({unit})"),
        (axes[1], "by_shear_angle", "model's |shear angle| (deg)"),
    ):
        bins = rec[key]
        x = range(len(bins))
        ax.bar(x, [b["mean_z2"] for b in bins], color="tab:orange")
        ax.axhline(1.0, color="k", ls="--", label="noise level")
        for k, b in enumerate(bins):
            share = "–" if b["share_of_excess"] is None else f"{100 * b['share_of_excess']:.0f} %"
            ax.annotate(
                f"rows {100 * b['share_of_rows']:.0f} %\nexcess {share}",
                (k, b["mean_z2"]),
                ha="center",
                va="bottom",
                fontsize=7,
            )
        ax.set_xticks(list(x), _labels(bins), fontsize=8)
        ax.set(xlabel=xlabel, ylabel="mean z² per component")
        ax.set_ylim(0.0, 1.2 * max([1.0] + [b["mean_z2"] for b in bins]))
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle(f"where the excess sits: {WORDS[rec['verdict']]}", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
