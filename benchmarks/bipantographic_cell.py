"""The figure docs/bipantographic_cell.png: one cell of the reconstructed bi-pantographic
lattice (Barchiesi et al. 2020 §3), with its local numbering and springs.

Run: ``.venv/bin/python benchmarks/bipantographic_cell.py [PATH]``.
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fabricsurf.network.bipantographic import R2, SEGMENTS, cell_geometry


def plot_cell(path: str = "docs/bipantographic_cell.png") -> None:
    """Figure of one cell (local numbering, springs) as reconstructed in
    :mod:`fabricsurf.network.bipantographic`."""
    x = cell_geometry(1.0)
    fig, ax = plt.subplots(figsize=(6, 6))
    c = np.sqrt(2)
    ax.plot([0, c, c, 0, 0], [0, 0, c, c, 0], ":", color="grey", lw=1)
    for p, q, sl, sr in SEGMENTS:
        for s in (sl, sr):
            ax.plot(*x[[p, s, q]].T, "k-", lw=1.5)
            side = "+" if s == sr else "-"
            ax.annotate(
                f"{side}π/3",
                x[s],
                xytext=(4, 4),
                textcoords="offset points",
                color="green",
                fontsize=7,
            )
    for t in R2:
        ax.plot(*x[list(t)].T, "r--", lw=1)
    ax.scatter(*x.T, s=120, facecolor="white", edgecolor="k", zorder=3)
    for k, p in enumerate(x):
        ax.text(*p, str(k), ha="center", va="center", fontsize=7, zorder=4)
    ax.scatter(*x[[5, 6, 7, 8, 9, 10, 11, 12]].T, s=300, facecolor="none", edgecolor="green")
    ax.set_title(
        "bi-pantographic cell [B §3] (reconstruction)\nblack: 16 extensional "
        "l0=ε/√3; green: 8 pivots φ0=±π/3;\nred dashed: 4 bending bars φ0=0 "
        "(k_r3 bars continue through vertices)",
        fontsize=8,
    )
    ax.set_aspect("equal")
    ax.set_xlabel("x / ε")
    ax.set_ylabel("y / ε")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


if __name__ == "__main__":
    plot_cell(*sys.argv[1:2])
