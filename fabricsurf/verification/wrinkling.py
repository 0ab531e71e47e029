"""References for the wrinkling indicator of the hemisphere plug-in
(experiments/forming/indicators.py):
the flange's out-of-plane amplitude and a buckling estimate of its unpressed strip.

**Amplitude.** Beyond the die's lip (current distance from the axis ρ ≥ R_o + r_d, where the
die's face is flat) an unwrinkled flange is a surface of revolution up to the four-fold
variation the fibres at ±θ give every forming field (with the mirror lines and the diagonal,
z(φ) = Σ_k a_k cos 4kφ). The flange's points, sampled on an n × n grid of the quarter's
reference blank, are put in bands of current ρ (``band`` mm wide); in each band z is fitted by
least squares with a quadratic in ρ and the harmonics cos 4φ and cos 8φ, each linear in ρ
(waves 2πρ/4 and 2πρ/8 long, the flange's own long-wave field, several times the wrinkles'
wavelength measured in docs/forming.md, "Wrinkling"), and the residual is the out-of-plane
deviation in shorter waves: the wrinkles. The amplitude is its largest magnitude. It is a
reference only where it converges under mesh refinement (benchmarks/wrinkling.py). The quarter
blank with mirror conditions on its mid-lines admits only wrinkles symmetric about them (z even
in φ about 0° and 90°), so modes without that symmetry are not seen by either the indicator or
this amplitude.

**Buckling estimate.** Between the end of the die's lip, ρ₀ = R_o + r_d, and the radius where
the holder's pressure is full, ρ₀ + 2 r_d (forming_tools.Tools.holder_weight), the flange is
held by neither tool: a strip of width b = 2 r_d compressed along the hoop as the flange draws
in. A long plate strip under longitudinal compression N buckles at N_cr = k π² D / b², k = 4
with simply supported edges, 6.97 with clamped ones (Timoshenko & Gere 1961, §9.2). The bending
stiffness of the fabric model for a cylindrical bend at angle α to a fibre of an orthogonal
net is D(α) = k_b (cos⁴α + sin⁴α) + k_t cos²α sin²α (NormalBending and Twist, K_L = κ cos²α,
K_M = κ sin²α, T = κ cos α sin α); its least value over α is used. The hoop compression is
N_θθ = T_l (l·e_θ)² + T_m (m·e_θ)² from the fibre tensions (the shear term's stress left out),
its mean over the strip's sample points; N_θθ < −N_cr predicts wrinkles.
"""

from __future__ import annotations

import math

import numpy as np
import ufl
from dolfinx import fem

from fabricsurf.discretise.energy import placement
from fabricsurf.discretise.evaluation import eval_points, interpolate_expression
from fabricsurf.experiments.forming import blank as forming_blank
from fabricsurf.experiments.forming import indicators as wrinkling
from fabricsurf.model.kinematics import l_dir, m_dir

HARMONICS = (1, 2)
"""The forming's own angular field in a band: cos 4kφ for these k (module docstring)."""
PLATE_K = {"simply supported": 4.0, "clamped": 6.97}
"""Buckling coefficients k of a long plate strip in compression along its length, N_cr =
k π² D / b² (Timoshenko & Gere 1961, §9.2)."""


def _grid(e, n: int) -> np.ndarray:
    half = 0.5 * e.setup.length
    x = np.linspace(0.0, half, n)
    X, Y = np.meshgrid(x, x, indexing="xy")
    return np.column_stack([X.ravel(), Y.ravel()])


def _polar(e, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ρ, φ, z) of the current positions of reference points P (the same on every rank)."""
    r = np.column_stack([P, np.zeros(len(P))]) + eval_points(e.problem.u, P)
    return np.hypot(r[:, 0], r[:, 1]), np.arctan2(r[:, 1], r[:, 0]), r[:, 2]


def lip_end(e) -> float:
    """ρ₀ = R_o + r_d: where the die's face becomes flat (mm; a circular opening's)."""
    if e.tools.outline.kind != "circle":
        raise ValueError("the wrinkling study reads a circular die opening")
    return float(e.tools.outline.corner + e.tools.lip.value)


def amplitude(e, n: int = 81, band: float = 1.0) -> dict:
    """The flange's out-of-plane deviation beyond its own long-wave field (module docstring)
    on an n × n reference grid of the quarter: ``points`` (n²×2), ``residual`` (mm, NaN off
    the flange), ``amplitude`` (its largest magnitude), ``bands`` (per band: inner ρ, points,
    largest residual). The same on every rank."""
    P = _grid(e, n)
    rho, phi, z = _polar(e, P)
    residual = np.full(len(P), np.nan)
    bands = []
    start = lip_end(e)
    for a in np.arange(start, np.nanmax(rho), band):
        s = (rho >= a) & (rho < a + band)
        if s.sum() < 3 * (3 + 2 * len(HARMONICS)):  # too few points to fit and leave a residual
            continue
        dr = rho[s] - (a + 0.5 * band)
        smooth = [np.ones(s.sum()), dr, dr**2]
        A = np.column_stack(
            smooth + [f * np.cos(4.0 * k * phi[s]) for k in HARMONICS for f in (1.0, dr)]
        )
        c, *_ = np.linalg.lstsq(A, z[s], rcond=None)
        residual[s] = z[s] - A @ c
        bands.append((float(a), int(s.sum()), float(np.abs(residual[s]).max())))
    return {
        "points": P,
        "residual": residual,
        "bands": bands,
        "amplitude": float(np.nanmax(np.abs(residual))) if bands else 0.0,
    }


def bending_stiffness(e) -> float:
    """min over α of D(α) = k_b (cos⁴α + sin⁴α) + k_t cos²α sin²α (N·mm; module docstring,
    experiments.wrinkling.bending_stiffness)."""
    return wrinkling.bending_stiffness(e.model)


def hoop_tension(e):
    """N_θθ = T_l (l·e_θ)² + T_m (m·e_θ)² (N/mm, UFL; module docstring)."""
    kin = e.problem.energy.kin
    t = e.problem.energy.tension_fields()
    r = placement(e.problem.u)
    rho = ufl.sqrt(r[0] ** 2 + r[1] ** 2 + 1e-12)
    e_t = ufl.as_vector([-r[1] / rho, r[0] / rho, 0.0])
    fl, fm = l_dir(kin.F, kin.L), m_dir(kin.F, kin.M)
    return t["tension_l"] * ufl.dot(fl, e_t) ** 2 + t["tension_m"] * ufl.dot(fm, e_t) ** 2


def buckling(e, n: int = 81) -> dict:
    """The buckling estimate of the unpressed strip (module docstring): ``hoop`` (mean N_θθ
    over the strip's sample points, N/mm), ``N_cr`` per edge condition, D, b, and ``ratio``
    −N_θθ / N_cr (simply supported: the lower load). The same on every rank."""
    P = _grid(e, n)
    rho, _, _ = _polar(e, P)
    r0, b = lip_end(e), 2.0 * float(e.tools.lip.value)
    strip = (rho >= r0) & (rho < r0 + b)
    V = fem.FunctionSpace(e.specimen.mesh, ("DG", 2))
    N = eval_points(interpolate_expression(hoop_tension(e), V), P[strip])[:, 0]
    hoop = float(N.mean()) if len(N) else 0.0
    D = bending_stiffness(e)
    cr = {k: v * math.pi**2 * D / b**2 for k, v in PLATE_K.items()}
    return {
        "hoop": hoop,
        "N_cr": cr,
        "D": D,
        "b": b,
        "points": int(strip.sum()),
        "ratio": -hoop / cr["simply supported"],
    }


def _marked(e, expr, P: np.ndarray) -> np.ndarray:
    """Which sample points a 0/1 indicator (UFL) marks, by its cell values."""
    V = fem.FunctionSpace(e.specimen.mesh, ("DG", 0))
    field = fem.Function(V)
    field.interpolate(fem.Expression(expr, V.element.interpolation_points()))
    return eval_points(field, P)[:, 0] > 0.5


def membrane_marks(e, P: np.ndarray) -> np.ndarray:
    """The plug-in indicator at reference points P, point by point: in the unheld strip (by the
    current radius) and the least principal value of the smoothed membrane force below −N_cr
    (experiments.wrinkling)."""
    rho, _, _ = _polar(e, P)
    r0, b = lip_end(e), 2.0 * float(e.tools.lip.value)
    force = eval_points(e.wrinkling.smoothed, P)[:, 0]
    return (rho >= r0) & (rho < r0 + b) & (force < -e.wrinkling.threshold())


def envelope(P: np.ndarray, wrinkled: np.ndarray, flange: np.ndarray, radius: float) -> np.ndarray:
    """The wrinkled region as an envelope: flange points within ``radius`` of a point whose
    residual exceeds the bound. A wrinkle is a wave, its residual passing through zero between
    crests, so the points above the bound alone are a set of stripes, not the region."""
    from scipy.spatial import cKDTree

    if not wrinkled.any():
        return np.zeros(len(P), bool)
    d, _ = cKDTree(P[wrinkled]).query(P, k=1)
    return flange & (d <= radius)


def compare(e, bound: float, curvatures: tuple[float, ...] | None = None, n: int = 81) -> dict:
    """What the indicators mark against the amplitude. The reference's wrinkled region: the
    sample points where |residual| > ``bound``, and its :func:`envelope` within r_d (half a
    strip's width). ``indicator``: the plug-in's (the membrane
    force in the unheld strip against its buckling force, e.area_fractions()) first, then the
    curvature flag for each κ_w of ``curvatures`` (default none; set through its fem.Constant,
    no recompilation, and restored), each with its area fraction of the blank, sample points,
    those on the flange, the overlap (points both mark) and those in the envelope. The same on
    every rank;
    ``points``, ``residual`` and ``marked`` (the plug-in indicator's sample points) are
    :func:`draw_map`'s."""
    amp = amplitude(e, n)
    P = amp["points"]
    flange = ~np.isnan(amp["residual"])
    wrinkled = flange & (np.abs(np.nan_to_num(amp["residual"])) > bound)

    region = envelope(P, wrinkled, flange, float(e.tools.lip.value))

    def row(kind: str, marked: np.ndarray, area: float, **extra) -> dict:
        return {
            "kind": kind,
            **extra,
            "area": area,
            "points": int(marked.sum()),
            "on_flange": int((marked & flange).sum()),
            "overlap": int((marked & wrinkled).sum()),
            "in_region": int((marked & region).sum()),
        }

    first = membrane_marks(e, P)
    rows = [
        row(
            "membrane force",
            first,
            e.area_fractions()["wrinkle"],
            threshold=e.wrinkling.threshold(),
        )
    ]
    ind, kin = e.indicators, e.problem.energy.kin
    flag = ind.wrinkle(kin, e.problem.energy.tension_fields())
    area = fem.form(flag * e.problem.dx)
    own = float(ind.curvature.value)
    try:
        for k in curvatures or ():
            ind.curvature.value = k
            fraction = (
                e.copies * e.comm.allreduce(fem.assemble_scalar(area)) / forming_blank.area(e.setup)
            )
            rows.append(row("curvature", _marked(e, flag, P), fraction, curvature=k))
    finally:
        ind.curvature.value = own
    return {
        "amplitude": amp["amplitude"],
        "bands": amp["bands"],
        "points": P,
        "residual": amp["residual"],
        "marked": first,
        "reference_area": float(wrinkled.mean()),
        "reference_points": int(wrinkled.sum()),
        "region_points": int(region.sum()),
        "indicator": rows,
    }


def draw_map(path, result: dict, blank: float, R: float) -> None:
    """The amplitude's residual (mm) on the reference quarter, the sample points the indicator
    marks (its first κ_w) as black dots, the punch's radius dashed (rank 0; :func:`compare`'s
    ``result`` with its ``marked`` points)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    P, res = result["points"], result["residual"]
    n = round(math.sqrt(len(P)))
    fig, ax = plt.subplots(figsize=(5, 4.2))
    half = 0.5 * blank
    lim = float(np.nanmax(np.abs(res))) if np.isfinite(res).any() else 1.0
    im = ax.imshow(
        res.reshape(n, n),
        origin="lower",
        extent=(0, half, 0, half),
        cmap="RdBu",
        vmin=-lim,
        vmax=lim,
    )
    marked = result["marked"]
    ax.plot(P[marked, 0], P[marked, 1], "k.", ms=2, label="indicator (membrane force)")
    ax.add_patch(plt.Circle((0, 0), R, fill=False, color="k", ls="--"))
    fig.colorbar(im, label="wrinkle: deviation from the long-wave field (mm)")
    ax.set(
        xlabel="x (mm, reference)",
        ylabel="y (mm, reference)",
        xlim=(0, half),
        ylim=(0, half),
        title="flange wrinkles and the indicator",
    )
    ax.legend(fontsize=8, loc="upper right")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
