"""The bias test's curves against the grip displacement: force and the shear angles at A and B
(``fabricsurf bias``: force.png; matplotlib, Agg; call on rank 0 only)."""

from __future__ import annotations

from pathlib import Path


def bias_curves(res, path: Path, label: str = "continuum") -> None:
    """Force and shear angles at A and B against ū of a bias run ``res`` (a
    :class:`~fabricsurf.experiments.bias_extension.BiasResult`: ``ubar``, ``force``,
    ``angle_A_deg``, ``angle_B_deg``), as a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    ax[0].plot(res.ubar, res.force, "o-", label=label)
    ax[0].set(xlabel="grip displacement ū (mm)", ylabel="reaction force (N)")
    ax[1].plot(res.ubar, res.angle_A_deg, "o-")
    ax[1].set(xlabel="ū (mm)", ylabel="shear angle at A (deg)")
    ax[2].plot(res.ubar, res.angle_B_deg, "o-")
    ax[2].set(xlabel="ū (mm)", ylabel="shear angle at B (deg)")
    ax[0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
