"""What demos/demo_woven_fabric.py and benchmarks/woven_real_yarns.py share: the Cao et al.
2008 bias-extension curve against the model: force errors over the curve and over ranges of
it, the ranges no elastic term can follow (named), the curve cut at a zone-C angle, the record
of the large-shear diagnosis, and the demo's figures. The three-zone kinematics and
normalisation (eqs. 13 and 18) are in :mod:`fabricsurf.experiments.three_zone`; the numbers
these give for the Cao curve are in docs/woven_fabric.md.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fabricsurf.experiments import three_zone as tz
from fabricsurf.model.terms import Term

KNEE = "initial knee (friction at the crossovers: no elastic term starts with a finite force)"
BEYOND = (
    "beyond locking (softer than any shear law on a net of inextensible yarns: the net "
    "extends along its yarns, yarn slip at the zone boundaries, or the grips slip)"
)
MIDDLE = "intermediate range"


def force_errors(model, measured) -> dict:
    """RMS and max |model − measured| in N and in % of the largest measured force."""
    e = np.asarray(model, float) - np.asarray(measured, float)
    fmax = float(np.max(np.abs(measured)))
    rms, mx = float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(e)))
    return {"rms_N": rms, "max_N": mx, "rms_pct": 100 * rms / fmax, "max_pct": 100 * mx / fmax}


def unexplained_ranges(d, error, measured, s_F: float, length: float, width: float) -> list[dict]:
    """Displacement ranges where |force error| exceeds three noise levels (the criterion of
    :func:`fabricsurf.inverse.diagnosis.report.where_unexplained`), each named. A range is the
    initial knee if every point before it has a measured force below three noise levels
    (there the data cannot tell any response from zero, so it is where the curve first
    departs); a range reaching the last point is beyond locking; anything else is an
    intermediate range."""
    d, error, measured = (np.asarray(a, float) for a in (d, error, measured))
    bad = np.abs(error) > 3.0 * s_F
    out, k = [], 0
    while k < len(d):
        if not bad[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(d) and bad[j + 1]:
            j += 1
        quiet_before = bool(np.all(np.abs(measured[:k]) < 3.0 * s_F))
        kind = KNEE if quiet_before else BEYOND if j == len(d) - 1 else MIDDLE
        g = np.degrees(tz.zone_c_shear_angle(d[[k, j]], length, width))
        out.append(
            {
                "kind": kind,
                "displacement_mm": [float(d[k]), float(d[j])],
                "zone_c_angle_deg": [float(g[0]), float(g[1])],
                "points": int(j - k + 1),
                "max_abs_error_N": float(np.max(np.abs(error[k : j + 1]))),
                "sign": "model above data" if error[k : j + 1].mean() > 0 else "model below data",
            }
        )
        k = j + 1
    return out


LARGE_SHEAR_BASE = ["fibre_stretch", "shear", "crossover_friction"]
"""The baseline of the large-shear diagnosis: the yarns' extensibility free (the net may extend
along its yarns, which a sticking glass net cannot), shear and the crossings' friction; its
candidates are :data:`LARGE_SHEAR_CANDIDATES`."""
LARGE_SHEAR_CANDIDATES = ["yarn_slip", "shear_locking"]


def large_shear_record(full, s_F: float, start: list[Term], diag) -> dict:
    """The whole-curve diagnosis ``diag`` of ``full`` (docs/woven_fabric.md "The large-shear
    range"), past 60 deg of zone-C shear too, beside the net of inextensible yarns with the
    model ``start`` fitted up to 60 deg (its three-zone force: the force of inextensible yarns
    on the fibre-aligned mesh, with no solve near the net's lock): χ² in the error unit ``s_F``
    and errors over the whole curve, up to and past 60 deg; ranking, verdict, what is not
    identifiable and the final model's unexplained ranges."""
    d, F, H, W = full.path, full.force, full.length, full.width
    past = np.degrees(tz.zone_c_shear_angle(d, H, W)) > 60.0

    def errors(model) -> dict:
        model = np.asarray(model, float)
        return {
            "chi2": float(np.sum(((model - F) / s_F) ** 2)),
            "whole": force_errors(model, F),
            "up_to_60_deg": force_errors(model[~past], F[~past]),
            "past_60_deg": force_errors(model[past], F[past]),
        }

    base, final = diag.base_fit, diag.final_fit
    fits = {
        k: {"terms": t, "params": {n: v for n, v in r.params().items() if n in t}}
        | errors(r.prediction[0].force)
        for k, t, r in (("baseline", diag.baseline, base), ("final", diag.terms, final))
    }
    return {
        "points": len(d),
        "past_60_deg_points": int(past.sum()),
        "error_unit_N": s_F,
        "inextensible_net_fitted_to_60_deg": errors(tz.kinematic_force(d, H, W, start)),
        **fits,
        "ranking": [
            {k: q.get(k) for k in ("effect", "score", "refit_chi2", "refit_params", "significant")}
            for q in diag.ranking
        ],
        "verdict": diag.verdict,
        "outcome": diag.outcome(),
        "not_identifiable": diag.not_identifiable,
        "unexplained": _unexplained(final.prediction[0].force, full, s_F),
    }


def _unexplained(model, full, s_F: float) -> list[dict]:
    """:func:`unexplained_ranges` of a model's force on the whole curve."""
    return unexplained_ranges(
        full.path, np.asarray(model) - full.force, full.force, s_F, full.length, full.width
    )


def up_to_angle(exp, max_deg: float):
    """A copy of the force-only bias experiment ``exp`` with the points whose zone-C angle
    (Cao et al. 2008 eq. 13) is at most ``max_deg``."""
    keep = np.degrees(tz.zone_c_shear_angle(exp.path, exp.length, exp.width)) <= max_deg
    n = int(keep.sum())
    return replace(
        exp, steps=np.arange(1, n + 1), path=exp.path[keep].copy(), force=exp.force[keep].copy()
    )


def range_errors(d, model, measured, lo: float, hi: float) -> dict:
    """:func:`force_errors` on the points with ``lo`` ≤ d ≤ ``hi`` (mm): the percentages are
    of the largest measured force in that range (``*_pct``) and of the whole curve's
    (``*_pct_of_curve``)."""
    d, model, measured = (np.asarray(a, float) for a in (d, model, measured))
    sel = (d >= lo) & (d <= hi)
    e = force_errors(model[sel], measured[sel])
    share = np.max(np.abs(measured[sel])) / np.max(np.abs(measured))
    return {
        **e,
        "rms_pct_of_curve": e["rms_pct"] * share,
        "max_pct_of_curve": e["max_pct"] * share,
        "points": int(sel.sum()),
        "range_mm": [lo, hi],
    }


def _angle_axis(ax, length: float, width: float) -> None:
    lock = tz.lock_displacement(length, width)
    sec = ax.secondary_xaxis(
        "top",
        functions=(
            lambda d: np.degrees(tz.zone_c_shear_angle(np.clip(d, 0, lock), length, width)),
            lambda g: tz.displacement_at_angle(np.radians(g), length, width),
        ),
    )
    sec.set_xlabel("zone-C shear angle, Cao eq. 13 (deg)")


def figures(
    out,
    exp,
    curves: dict,
    knee: tuple[float, float],
    err_unit: float,
    prediction: tuple,
    valid_to: float,
) -> None:
    """The woven demo's figures: force and residual against displacement, the normalised shear
    force (Cao et al. 2008 eq. 18) of the data and of each model with the knee range marked,
    and the prediction of the other specimen size (rank 0 only)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    H, W, d, F = exp.length, exp.width, exp.path, exp.force
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.3))
    ax[0].plot(d, F, "ko", ms=4, label="Cao et al. 2008 (digitised)")
    for k, v in curves.items():
        ax[0].plot(d[: len(v)], v, "-", label=k)
        ax[1].plot(d[: len(v)], v - F[: len(v)], "o-", ms=3, label=k)
    ax[1].axhspan(-3 * err_unit, 3 * err_unit, color="0.85", label="±3 error units")
    for a in ax:
        a.axvspan(*knee, color="C3", alpha=0.1, label="knee range")
        _angle_axis(a, H, W)
        a.set_xlabel("crosshead displacement d (mm)")
    ax[0].set(ylabel="force (N)")
    ax[1].set(ylabel="force residual model − data (N)", ylim=(-2, 2))
    ax[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "residual_vs_displacement.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    g, fsh = tz.normalised_shear_force(d, F, H, W)
    ax.plot(np.degrees(g), fsh, "ko", ms=4, label="data, eq. 18")
    for k, v in curves.items():
        gm, fm = tz.normalised_shear_force(d[: len(v)], v, H, W)
        ax.plot(np.degrees(gm), fm, "-", label=f"{k}, eq. 18")
    ax.axvspan(
        *np.degrees(tz.zone_c_shear_angle(np.array(knee), H, W)),
        color="C3",
        alpha=0.1,
        label="knee range",
    )
    ax.set(
        xlabel="zone-C shear angle γ (deg)",
        ylabel="normalised shear force (N/mm)",
        xlim=(0, 75),
        ylim=(0, 0.06),
    )
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "normalised_shear_force.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    (dp, Fp, half), (Lp, Wp) = prediction, (450.0, 150.0)
    ax.plot(dp, Fp, "-", label="150 × 450 mm, prediction")
    ax.fill_between(dp, Fp - half, Fp + half, alpha=0.3, label="95 % band (linearised)")
    ax.axvspan(valid_to, max(dp), color="0.85", label="beyond the model's own validity")
    ax.set(xlabel="crosshead displacement d (mm)", ylabel="force (N)")
    ax.legend(fontsize=8)
    _angle_axis(ax, Lp, Wp)
    fig.tight_layout()
    fig.savefig(out / "prediction_150x450.png", dpi=120)
    plt.close(fig)


def read_json(comm, path) -> dict:
    """A JSON file written by rank 0, read there and broadcast."""
    import json
    from pathlib import Path

    return comm.bcast(json.loads(Path(path).read_text()) if comm.rank == 0 else None)


def write_curve(path, d, force) -> None:
    """A force curve as CSV with the columns ``displacement,force`` (mm, N)."""
    np.savetxt(
        path,
        np.column_stack([d, force]),
        delimiter=",",
        fmt="%.6g",
        header="displacement,force",
        comments="",
    )
