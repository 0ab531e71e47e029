"""Numerical homogenisation of the bi-pantographic lattice (Barchiesi et al. 2020, §3, eqs. 18-20).

The L- and M-beams of :func:`~fabricsurf.network.bipantographic.bipantographic_lattice`
share only their axis nodes (vertices and centres), so one pantographic beam carries the
whole energy of a fibre family: a chain of rhombi A_k-L_k-A_{k+1}-R_k (sides eps/sqrt(3) at
gamma = pi/6 to the axis) with, per rhombus, 4 extensional springs k_e and 2 pivots k_r1 at
the side nodes, and at every interior axis node A_k the two straight bars
{L_{k-1}, A_k, R_k}, {R_{k-1}, A_k, L_k} (k_r2, phi0 = 0), exactly as in the 2D cell.
Micro-macro map: the axis nodes are put on the macro placement chi (pitch eps along the
beam), the side nodes are relaxed; beams are eps apart, so the energy per unit area is the
energy per unit reference beam length / eps. Matching it with [B (2)] per family,

    W = K_S f(rho)^2 + a_theta(rho) theta'^2 + a_rho(rho) rho'^2,
    f = acos(1 - 2 rho^2 c^2) - pi + 2 gamma,  c = cos gamma,

gives K_S (uniform stretch), a_theta (axis on a circle, theta' = kappa rho) and a_rho
(sinusoidal stretch of small amplitude), each measured on the interior of a long chain.
With 1/a_theta(1) = 1/K_F + 18/K_E and 3/a_rho(1) = 1/K_F + 2/K_E ([B (2)] at rho = 1)
the pair (K_E, K_F) follows in closed form.

Hand limits (linearised chain, checked by the tests):

* uniform stretch: pivots (2 per rhombus, turning 2 theta) in series with the side
  extension, K_S = 1 / (96 [cos^2 g / (4 k_e) + eps^2 sin^2 g / (24 k_r1)]);
  inextensible sides give the pivot count K_S = k_r1 / eps^2;
* bending at rho = 1: the bars are in series with the sideways shift of both side nodes
  (pivots + extension), a_theta(1) = k_r2 B / (k_r2 + B), B = k_r1 + k_e eps^2 / 18;
  for k_r1 = 0 this is [B (2)] with K_E = k_e eps^2, K_F = k_r2 (rigid rhombi: k_r2).

a_rho depends on the O(eps) part of the micro-macro map: taking the chord stretches as
samples of rho at the rhombus midpoints instead of chi at the axis nodes adds K_S eps^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabricsurf.network.bipantographic import EPS_B, TABLE3
from fabricsurf.network.engine import SpringNetwork
from fabricsurf.network.equilibrium import newton

GAMMA = np.pi / 6
C = np.cos(GAMMA)


@dataclass
class Chain:
    """A pantographic beam of ``n`` rhombi; ``owner_*`` give the rhombus (extension,
    pivot) or axis node (bending) of every spring, for interior energy windows."""

    net: SpringNetwork
    n: int
    eps: float
    owner_ext: np.ndarray
    owner_rot: np.ndarray
    is_bend: np.ndarray


def pantographic_chain(
    n: int,
    eps: float = EPS_B,
    k_e: float = TABLE3["k_e"],
    k_r1: float = TABLE3["k_r1"],
    k_r2: float = TABLE3["k_r2"],
) -> Chain:
    """Straight chain: axis nodes 0..n at (k eps, 0), side nodes L_k = n+1+2k, R_k = L_k+1.

    Springs as in one beam of the 2D cell [B (20)] (``bipantographic.SEGMENTS``, ``R2``):
    pivots P -> S -> Q with phi0 = +-pi/3 from the reference, bars at interior nodes.
    """
    k = np.arange(n)
    a, b, lft = k, k + 1, n + 1 + 2 * k
    rgt = lft + 1
    X = np.zeros((3 * n + 1, 2))
    X[: n + 1, 0] = eps * np.arange(n + 1)
    h = eps / (2 * np.sqrt(3.0))
    X[lft] = np.stack([eps * (k + 0.5), np.full(n, h)], 1)
    X[rgt] = np.stack([eps * (k + 0.5), np.full(n, -h)], 1)
    ext = np.concatenate([np.stack(p, 1) for p in ((a, lft), (a, rgt), (lft, b), (rgt, b))])
    piv = np.concatenate([np.stack((a, s, b), 1) for s in (rgt, lft)])
    m = np.arange(1, n)
    bend = np.concatenate(
        [np.stack((lft[m - 1], m, rgt[m]), 1), np.stack((rgt[m - 1], m, lft[m]), 1)]
    )
    rot = np.concatenate([piv, bend])
    k_rot = np.concatenate([np.full(len(piv), k_r1), np.full(len(bend), k_r2)])
    net = SpringNetwork(X, ext, k_e, l0=eps / np.sqrt(3.0), rot=rot, k_rot=k_rot)
    is_bend = np.r_[np.zeros(len(piv), bool), np.ones(len(bend), bool)]
    return Chain(net, n, eps, np.tile(k, 4), np.r_[k, k, m, m], is_bend)


def relax(ch: Chain, axis: np.ndarray) -> np.ndarray:
    """Axis nodes at ``axis`` (n+1, 2); side nodes minimise the energy (Newton [B (24)]).

    Start: each rhombus with inextensible sides on its chord (width from the chord length);
    converged at a residual of 1e-12 (k_e eps + k_r / eps) N.
    """
    n, l0 = ch.n, ch.eps / np.sqrt(3.0)
    x = ch.net.X.copy()
    x[: n + 1] = axis
    d = axis[1:] - axis[:-1]
    ell = np.linalg.norm(d, axis=1)
    half = np.sqrt(np.maximum(l0**2 - (ell / 2) ** 2, (0.05 * l0) ** 2))
    nrm = np.stack([-d[:, 1], d[:, 0]], 1) / ell[:, None]
    mid = 0.5 * (axis[1:] + axis[:-1])
    x[n + 1 :: 2] = mid + half[:, None] * nrm
    x[n + 2 :: 2] = mid - half[:, None] * nrm
    fixed = np.zeros((len(x), 2), bool)
    fixed[: n + 1] = True
    scale = ch.net.k_ext.max() * ch.eps + ch.net.k_rot.max() / ch.eps  # force scale (N)
    x, info = newton(ch.net, x, fixed.ravel(), rtol=1e-12, atol=1e-12 * scale, maxit=50)
    if not info.converged:
        raise RuntimeError(f"chain relaxation failed (residual {info.residual:.2e} N)")
    return x


def window_density(ch: Chain, x: np.ndarray, lo: int, hi: int) -> float:
    """Energy per unit reference area (N/mm) of rhombi lo..hi-1 and axis nodes lo..hi
    (end nodes weighted 1/2): window energy / ((hi - lo) eps * eps)."""
    ee, er = ch.net.spring_energies(x)
    w_e = ((ch.owner_ext >= lo) & (ch.owner_ext < hi)).astype(float)
    own = ch.owner_rot
    w_r = np.where(ch.is_bend, (own >= lo) & (own <= hi), (own >= lo) & (own < hi)).astype(float)
    w_r[ch.is_bend & ((own == lo) | (own == hi))] = 0.5
    return float(w_e @ ee + w_r @ er) / ((hi - lo) * ch.eps**2)


def pivot_measure(rho: np.ndarray | float) -> np.ndarray | float:
    """f(rho) = acos(1 - 2 rho^2 c^2) - pi + 2 gamma of [B (2)]."""
    return np.arccos(1 - 2 * np.asarray(rho) ** 2 * C**2) - np.pi + 2 * GAMMA


def _window(n: int, margin: int) -> tuple[int, int]:
    if n <= 2 * margin:
        raise ValueError(f"chain of {n} rhombi has no interior beyond margin {margin}")
    return margin, n - margin


def uniform_density(ch: Chain, rho: float, margin: int = 10) -> float:
    """Energy per area of the straight chain with axis pitch rho eps [B (2), first term]."""
    axis = np.zeros((ch.n + 1, 2))
    axis[:, 0] = rho * ch.eps * np.arange(ch.n + 1)
    return window_density(ch, relax(ch, axis), *_window(ch.n, margin))


def k_s_from_chain(ch: Chain, h: float = 1e-3) -> float:
    """K_S = W / f^2 at rho = 1 +- h (the symmetric pair cancels the O(h) error) [B (2)]."""
    w = uniform_density(ch, 1 + h) + uniform_density(ch, 1 - h)
    return w / (pivot_measure(1 + h) ** 2 + pivot_measure(1 - h) ** 2)


def k_s_series(k_e: float, k_r1: float, eps: float) -> float:
    """Hand K_S of the linearised rhombus: pivots in series with the side extension."""
    return 1.0 / (96 * (C**2 / (4 * k_e) + eps**2 * np.sin(GAMMA) ** 2 / (24 * k_r1)))


def bending_density(ch: Chain, kappa: float, rho: float = 1.0, margin: int = 10) -> float:
    """Energy per area with the axis nodes on a circle of radius 1/kappa, arc pitch rho eps
    (chord 2 R sin(rho eps / 2R)), centred on the chain so the window is symmetric."""
    phi = kappa * rho * ch.eps * (np.arange(ch.n + 1) - ch.n / 2)
    axis = np.stack([np.sin(phi), 1 - np.cos(phi)], 1) / kappa
    return window_density(ch, relax(ch, axis), *_window(ch.n, margin))


def a_theta_from_chain(ch: Chain, kappa: float, rho: float = 1.0) -> float:
    """a_theta(rho) = (W - W_uniform(rho)) / (d theta / d alpha)^2, theta' = kappa rho."""
    return (bending_density(ch, kappa, rho) - uniform_density(ch, rho)) / (kappa * rho) ** 2


def a_theta_series(k_e: float, k_r1: float, k_r2: float, eps: float) -> float:
    """Hand a_theta(1): bars k_r2 in series with B = k_r1 + k_e eps^2 / 18 (docstring)."""
    b = k_r1 + k_e * eps**2 / 18
    return k_r2 * b / (k_r2 + b)


def a_rho_from_chain(
    ch: Chain, wavelength: int, rho: float = 1.0, amp: float = 1e-4, margin: int = 10
) -> float:
    """a_rho(rho) from rho(s) = rho + amp cos(q s), q = 2 pi / (wavelength eps): axis nodes
    at chi(s) = rho s + amp sin(q s) / q, window = whole wavelengths. The uniform part, the
    mean of W_u(rho + amp cos) = W_u + W_u'' amp^2 / 4 + O(amp^4), is removed with the
    chain's own W_u(rho), W_u(rho +- amp): a_rho = (W - mean W_u) / mean(rho'^2)."""
    q = 2 * np.pi / (wavelength * ch.eps)
    s = ch.eps * (np.arange(ch.n + 1) - ch.n // 2)
    axis = np.stack([rho * s + amp * np.sin(q * s) / q, np.zeros_like(s)], 1)
    x = relax(ch, axis)
    periods = (ch.n - 2 * margin) // wavelength
    if periods < 1:
        raise ValueError(f"chain of {ch.n} rhombi too short for wavelength {wavelength}")
    lo = ch.n // 2 - periods * wavelength // 2
    w = window_density(ch, x, lo, lo + periods * wavelength)
    w_pm = uniform_density(ch, rho + amp) + uniform_density(ch, rho - amp)
    w_u = 0.5 * uniform_density(ch, rho) + 0.25 * w_pm
    return (w - w_u) / (amp**2 * q**2 / 2)


def moduli_from_coefficients(a_theta: float, a_rho: float) -> tuple[float, float]:
    """(K_E, K_F) from a_theta(1) = K_E K_F/(K_E + 18 K_F), a_rho(1) = 3 K_E K_F/(K_E + 2 K_F):
    linear in (1/K_E, 1/K_F); positive only if 3 a_theta < a_rho < 27 a_theta (else NaN)."""
    inv_e = (1 / a_theta - 3 / a_rho) / 16
    inv_f = 1 / a_theta - 18 * inv_e
    if inv_e <= 0 or inv_f <= 0:
        return float("nan"), float("nan")
    return 1 / inv_e, 1 / inv_f


def coefficients(rho: np.ndarray | float, K_E: float, K_F: float) -> tuple:
    """(a_theta(rho), a_rho(rho)) of [B (2)] (N mm)."""
    x = np.asarray(rho) ** 2 * C**2
    d = K_E - 8 * K_F * C**2
    return (
        K_E * K_F * (x - 1) / (x * d - K_E),
        K_E * K_F * x / ((1 - x) * (8 * K_F + np.asarray(rho) ** 2 * d)),
    )


def _richardson(f, h: float) -> float:
    """Limit h -> 0 of f(h) = f0 + O(h^2) from f(h) and f(h/2)."""
    return (4 * f(h / 2) - f(h)) / 3


def identify_macro(
    k_e: float = TABLE3["k_e"],
    k_r1: float = TABLE3["k_r1"],
    k_r2: float = TABLE3["k_r2"],
    eps: float = EPS_B,
    n: int = 80,
) -> dict:
    """Effective [B (2)] moduli of the lattice at finite eps by energy matching on a chain.

    Returns K_S (N/mm), a_theta, a_rho (rho = 1, Richardson-extrapolated to kappa eps,
    q eps -> 0), K_E, K_F (N mm; NaN if no positive pair reproduces both coefficients), and
    the asymptotic identification of [B (2)] (eps -> 0 scaling: K_S = k_r1/eps^2,
    K_E = k_e eps^2, K_F = k_r2) under ``asymptotic``; ``feasible`` is False when
    a_rho(1) is outside (3, 27) a_theta(1), i.e. no eq. (2) material has both coefficients.
    """
    ch = pantographic_chain(n, eps, k_e, k_r1, k_r2)
    a_t = _richardson(lambda h: a_theta_from_chain(ch, h / eps), 0.1)
    a_r = _richardson(lambda h: a_rho_from_chain(ch, round(2 * np.pi / h)), np.pi / 12)
    K_E, K_F = moduli_from_coefficients(a_t, a_r)
    asym = {"K_S": k_r1 / eps**2, "K_E": k_e * eps**2, "K_F": k_r2}
    return {
        "K_S": k_s_from_chain(ch),
        "a_theta": a_t,
        "a_rho": a_r,
        "K_E": K_E,
        "K_F": K_F,
        "feasible": bool(np.isfinite(K_E)),
        "asymptotic": asym,
    }
