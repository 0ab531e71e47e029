"""The computations of demos/demo_dispersion.py: part 1, the chain of Mühlhaus & Oka 1996 §2
against its truncated gradient continua; part 2, waves along the fibres of the Hencky lattice
against the fabric continuum with and without its gradient terms. Each returns the summary
entries (every scalar agreed across ranks) and the arrays the figures draw."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from research.studies import dispersion as dp

ORDERS = (2, 4, 6)
NEXT = {2: -1.0 / 12.0, 4: 1.0 / 360.0, 6: -1.0 / 20160.0}
"""The first neglected coefficient of v_p²/c0² for each truncation (eq. 15)."""


def agreed(comm: MPI.Comm, x: float) -> float:
    """A scalar reduced over the ranks (max); asserts that all ranks computed the same value."""
    hi, lo = comm.allreduce(float(x), op=MPI.MAX), comm.allreduce(float(x), op=MPI.MIN)
    assert hi == lo or abs(hi - lo) <= 1e-12 * max(1.0, abs(hi)), (hi, lo)
    return hi


def w2_formula(p: int, q: np.ndarray, k: float, m: float, D: float) -> np.ndarray:
    """ω² of the ∂^p continuum: c0² q² v_p²/c0² with the truncated series (eqs. 10, 15)."""
    return k * D**2 / m * q**2 * dp.vp2_truncated(q * D, p)


def chain_modes(comm: MPI.Comm, N: int, D: float, k: float, m: float) -> tuple[dict, dict]:
    """Chain modes from the network engine against eq. (12), and the continuum modes (dolfinx,
    P5 with C0 interior penalty) against their formulas, error orders and departure points."""
    q = dp.fixed_chain_wavenumbers(N, D)
    qd = q * D
    w2_chain = dp.chain_modes(N, k, m, D)
    cont = dp.GradientContinuum1D(comm, (N + 1) * D, 2 * (N + 1), degree=5)
    w2_fe, modes = {}, {}
    for p in ORDERS:
        w2_fe[p], overlap, _, modes[p] = cont.modes(*dp.gradient_moduli(p, k, D), m / D, N)
        assert overlap.min() > 0.999, f"order {p}: a computed mode is not a sine ({overlap.min()})"
    low = qd <= 1.5
    res: dict = {"N": N, "chain_engine_max_rel_err_vs_eq12":
                 agreed(comm, np.max(np.abs(w2_chain / dp.omega2_chain(qd, k, m) - 1.0))),
                 "continuum": {}, "departure_qD_vp_1pct": {}}
    xf = np.linspace(1e-3, np.pi, 20001)
    for p in ORDERS:
        err = np.abs(w2_fe[p] / w2_formula(p, q, k, m, D) - 1.0)
        e = w2_chain - w2_fe[p]
        sel = (np.abs(e) > 1e-6) & (qd <= 1.6)  # well above round-off, in the asymptotic range
        i0 = int(np.flatnonzero(sel)[0])
        lead = NEXT[p] * k / m * qd[i0] ** (p + 2)
        res["continuum"][str(p)] = {
            "fe_max_rel_err_vs_formula_qD_le_1.5": agreed(comm, err[low].max()),
            "fe_max_rel_err_vs_formula_all": agreed(comm, err.max()),
            "omega2_error_order_measured": agreed(comm, dp.fit_order(qd[sel], e[sel])),
            "omega2_error_order_expected": p + 2,
            "fit_qD_range": [agreed(comm, qd[sel].min()), agreed(comm, qd[sel].max())],
            "error_over_leading_term_at_qD": [agreed(comm, qd[i0]), agreed(comm, e[i0] / lead)],
        }
        x_an = dp.departure_point(xf, np.sqrt(dp.vp2_truncated(xf, p) / dp.vp2_exact(xf)))
        x_num = dp.departure_point(qd, np.sqrt(w2_fe[p] / w2_chain))
        res["departure_qD_vp_1pct"][str(p)] = {"formula": agreed(comm, x_an),
                                               "computed": agreed(comm, x_num)}
    return res, {"qd": qd, "w2_chain": w2_chain, "w2_fe": w2_fe, "modes": modes, "cont": cont}


def ill_posedness(comm: MPI.Comm, Ns: int, D: float, k: float, m: float) -> dict:
    """Smallest eigenvalue of the ∂⁴ and ∂⁶ continua on a short domain under refinement."""
    hs, lmin = [], {4: [], 6: []}
    for cpd in (2, 4, 8):
        short = dp.GradientContinuum1D(comm, (Ns + 1) * D, cpd * (Ns + 1), degree=5)
        hs.append(D / cpd)
        for p in (4, 6):
            lmin[p].append(agreed(comm, short.modes(*dp.gradient_moduli(p, k, D), m / D, 1)[2]
                                  .min()))
    q1 = np.pi / ((Ns + 1) * D)
    return {"h_over_D": hs, "min_eigenvalue_order4": lmin[4],
            "min_eigenvalue_order6": lmin[6],
            "order4_min_eigenvalue_exponent_in_h":
                agreed(comm, dp.fit_order(np.array(hs), np.array(lmin[4]))),
            "order6_first_mode_formula": agreed(comm, w2_formula(6, np.array([q1]), k, m, D)[0])}


def lattice_bloch(kl: float, ks: float, ag: float, qq: np.ndarray, eps: float, rho: float
                  ) -> tuple[np.ndarray, ...]:
    """Bloch ω² (longitudinal, transverse) of a 5x5 Hencky lattice patch, from its Hessian."""
    from fabricsurf.network.hencky import hencky_lattice, lattice_from_continuum

    lat = hencky_lattice(4 * eps, 4 * eps, eps, (0.0, 90.0),
                         **lattice_from_continuum(kl, ks, ag, eps, (0.0, 90.0)))
    H = lat.net.hessian(lat.net.X)
    return dp.bloch_omega2(H, lat.net.X, int(lat.grid[2, 2]), qq, lat.L, rho * eps**2)


def fabric_waves(comm: MPI.Comm, cont, q: np.ndarray, moduli: dict, betas: np.ndarray
                 ) -> tuple[dict, dict]:
    """Part 2: departure points of the fabric continua from the lattice's Bloch waves, the
    dolfinx modes of two of them against their formulas, and the transverse departure against
    β = A_g/(k_s ε²). ``cont`` and its wavenumbers ``q`` are part 1's mesh and modes."""
    eps, rho, k_l, k_s, A_g = (moduli[n] for n in ("eps_mm", "rho", "k_l", "k_s", "A_g"))
    xg = np.geomspace(1e-4, np.pi, 4000)  # qε
    qg = xg / eps
    wl, wt = lattice_bloch(k_l, k_s, A_g, qg, eps, rho)
    res: dict = {"eps_mm": eps, "k_l": k_l, "k_s": k_s, "A_g": A_g, "beta": A_g / (k_s * eps**2),
                 "bloch_vs_closed_form_max_rel_err": agreed(comm, max(
                     np.max(np.abs(wl / dp.hencky_omega2(qg, eps, k_l, 0.0, rho) - 1)[xg > 1e-2]),
                     np.max(np.abs(wt / dp.hencky_omega2(qg, eps, k_s, A_g, rho) - 1)[xg > 1e-2]))),
                 "departure_qeps_vp_1pct": {}, "fe_max_rel_err_vs_formula": {}}
    A_s = k_l * eps**2 / 12.0  # the size of the Taylor coefficient of the lattice
    continua = {
        "longitudinal: fibre_stretch": (k_l, 0.0, wl),
        "longitudinal: + stretch_gradient A_s=+k_l eps^2/12": (k_l, A_s, wl),
        "longitudinal: + stretch_gradient A_s=-k_l eps^2/12 (Taylor, ill-posed)": (k_l, -A_s, wl),
        "transverse: shear": (k_s, 0.0, wt),
        "transverse: + geodesic_bending": (k_s, A_g, wt),
    }
    vp_ratio = {}
    for name, (k2, A, w_lat) in continua.items():
        vp_ratio[name] = np.sqrt(np.maximum(dp.fabric_omega2(qg, k2, A, rho), 0.0) / w_lat)
        res["departure_qeps_vp_1pct"][name] = agreed(comm, dp.departure_point(xg, vp_ratio[name]))
    for name, (k2, A) in {"longitudinal A_s>0": (k_l, A_s),
                          "transverse + geodesic_bending": (k_s, A_g)}.items():
        res["fe_max_rel_err_vs_formula"][name] = fe_against_formula(comm, cont, q * eps, k2, A,
                                                                    eps, rho)
    res["departure_vs_beta"] = departure_vs_beta(comm, moduli, betas, xg)
    dep = res["departure_qeps_vp_1pct"]
    res["geodesic_bending_moves_departure_by_factor"] = (
        dep["transverse: + geodesic_bending"] / dep["transverse: shear"])
    return res, {"xg": xg, "qg": qg, "wl": wl, "wt": wt, "continua": list(continua),
                 "vp_ratio": vp_ratio}


def fe_against_formula(comm: MPI.Comm, cont, qe: np.ndarray, k2: float, A: float, eps: float,
                       rho: float) -> dict:
    """The dolfinx modes of ρω² = k2 q² + A q⁴ against the formula at the wavenumbers qε =
    ``qe``. A stiff A makes K ill-conditioned: the low modes are then accurate only to the
    round-off floor eps·max|λ|/ω_1², reported with the errors."""
    q = qe / eps
    w2c, _, lam_all, _ = cont.modes(k2, A, 0.0, rho, len(q))
    rel = np.abs(w2c / dp.fabric_omega2(q, k2, A, rho) - 1)
    return {"q_eps_le_1.5": agreed(comm, rel[qe <= 1.5].max()), "all": agreed(comm, rel.max()),
            "roundoff_floor": agreed(comm, np.finfo(float).eps * np.abs(lam_all).max()
                                     / w2c.min())}


def departure_vs_beta(comm: MPI.Comm, moduli: dict, betas: np.ndarray, xg: np.ndarray) -> dict:
    """The transverse departure point (qε on the grid ``xg``) of the shear-only and of the
    shear + geodesic_bending continuum from the lattice, for A_g = β k_s ε²."""
    eps, rho, k_l, k_s = (moduli[n] for n in ("eps_mm", "rho", "k_l", "k_s"))
    qg = xg / eps
    dep = {"shear": [], "shear + geodesic_bending": []}
    for b in betas:
        wt_b = lattice_bloch(k_l, k_s, b * k_s * eps**2, qg, eps, rho)[1]
        for key, A in (("shear", 0.0), ("shear + geodesic_bending", b * k_s * eps**2)):
            r = np.sqrt(dp.fabric_omega2(qg, k_s, A, rho) / wt_b)
            dep[key].append(agreed(comm, dp.departure_point(xg, r)))
    return {"beta": betas.tolist(), **dep}
