"""The micro-macro identification of the Hencky lattice (fabricsurf/network/hencky.py): the
continuum moduli that its springs stand for, and back (derivation in ``docs/network.md`` and
``docs/vocabulary.md``). The lattice's construction needs none of it; the generator of lattice
data, the dispersion checks and the demos convert moduli with it.

θ0 is the reference angle between L and M and ``s0 = sin θ0``; a node stands for the skew
cell ``eps L x eps M`` of area ``A = eps^2 s0``. For a smooth placement r(X) evaluated at
the nodes, Taylor expansion in eps gives, per node (one spring of each family, one bending
triple per fibre, four quadrant springs)::

    L spring:   1/2 k_e eps^2 (lam - 1)^2          + O(eps^4)   (at the spring midpoint)
    L bending:  turning angle = eps (p . r_LL) / lam + O(eps^3)
                -> 1/2 k_b eps^2 (p . r_LL)^2 / lam^2
    shear:      each quadrant angle changes by -+gamma + O(eps), the O(eps) parts of opposite
                quadrants cancelling; gamma = θ0 - θ, θ the angle between l and m
                -> 1/2 k_sh gamma^2 + 1/4 k_sh4 gamma^4 + 1/6 k_sh6 gamma^6   + O(eps^2)

and dividing by A (p = l rotated +90 deg)::

    k_l = k_m = k_e / s0            (N/mm)   fibre_stretch
    k_s       = k_sh / (eps^2 s0)   (N/mm)   shear
    k4, k6    = k_sh4, k_sh6 / (eps^2 s0)  (N/mm)   shear_locking
    A_g       = k_b / s0            (N mm)   geodesic_bending   (exact only at lam ~ 1)
    T_s       = f_slip / (eps s0)   (N/mm)   yarn_slip (slip strain eps_s = eps_slip)

Couplings beyond the vocabulary (:mod:`fabricsurf.network.couplings`; per quadrant the arm
strains are exactly lam - 1, mu - 1 and the angle change -+gamma for an affine placement, so
these are exact at any strain)::

    shear-tension   1/2 k_s (1 + c_st ((lam-1) + (mu-1))) gamma^2   c_st the same number
                    (the continuum term 1/2 k_c gamma^2 ((lam-1)+(mu-1)), k_c = c_st k_s)
    crimp           k_x (lam - 1)(mu - 1):  k_xc = k_x eps^2 s0   (N mm per crossing)
    compression     fibre_stretch with 1/2 (1 - s_comp) k_l (lam - 1)^2 for lam < 1: s_comp the
                    same number (= fibre_stretch at (1 - s_comp) k_l plus 1/2 s_comp k_l
                    max(lam - 1, 0)^2)

(a slipping spring's energy f_slip eps eps_s ln cosh((lam - 1)/eps_s) per node, exact for an
affine placement).

For an affine placement the quadrant changes are exactly -+gamma, so the shear identification
is exact at any gamma (tested with a large shear in ``tests/test_network_lattices.py``).

The bending identification holds at lam = 1: the lattice density is
``1/2 k_b (p . r_LL)^2 / lam^2`` versus ``1/2 A_g (p . r_LL)^2`` in the continuum, a relative
difference ``2 (lam - 1)`` at small fibre strain. The energy-density error of smooth
placements is O(eps^2) (measured in ``tests/test_network_lattices.py``).
"""

from __future__ import annotations

from fabricsurf.defaults import FRICTION_ANGLE
from fabricsurf.network.hencky import fibre_frame


def lattice_from_continuum(
    k_l: float,
    k_s: float,
    A_g: float,
    spacing: float,
    angles_deg: tuple[float, float] = (45.0, -45.0),
    k4: float = 0.0,
    k6: float = 0.0,
    tau_f: float = 0.0,
    gamma_f: float = FRICTION_ANGLE,
    T_s: float = 0.0,
    eps_s: float = 1.0,
    c_st: float = 0.0,
    k_x: float = 0.0,
    s_comp: float = 0.0,
) -> dict:
    """Lattice stiffnesses for continuum moduli (module docstring), ready for
    :func:`~fabricsurf.network.hencky.hencky_lattice`: ``k_e`` (N/mm), ``k_sh``, ``k_sh4``,
    ``k_sh6``, ``k_b``, ``m_shf`` (N mm), ``gamma_f`` (rad), ``f_slip`` (N) and ``eps_slip``,
    and the couplings ``c_st``, ``k_xc`` (N mm) and ``s_comp``.

    ``k_l`` (N/mm, both families), ``k_s`` and the ``shear_locking`` moduli ``k4``, ``k6``
    (N/mm), ``A_g`` (N mm); the ``crossover_friction`` modulus ``tau_f`` (N/mm) and its shape
    angle ``gamma_f``; the ``yarn_slip`` tension ``T_s`` (N/mm) and its slip strain ``eps_s``;
    the shear-tension coupling ``c_st`` (dimensionless), the crimp interchange ``k_x`` (N/mm)
    and the compression softness ``s_comp`` of the fibres (dimensionless);
    spacing eps (mm). The node area ``eps^2 sin θ0`` scales all.
    """
    s0 = fibre_frame(angles_deg)[0]
    cell = s0 * spacing**2
    return {
        "k_e": k_l * s0,
        "k_sh": k_s * cell,
        "k_b": A_g * s0,
        "k_sh4": k4 * cell,
        "k_sh6": k6 * cell,
        "m_shf": tau_f * cell,
        "gamma_f": gamma_f,
        "f_slip": T_s * s0 * spacing,
        "eps_slip": eps_s,
        "c_st": c_st,
        "k_xc": k_x * cell,
        "s_comp": s_comp,
    }


def continuum_from_lattice(
    k_e: float,
    k_sh: float,
    k_b: float,
    spacing: float,
    angles_deg: tuple[float, float] = (45.0, -45.0),
    k_sh4: float = 0.0,
    k_sh6: float = 0.0,
    m_shf: float = 0.0,
    gamma_f: float = FRICTION_ANGLE,
    f_slip: float = 0.0,
    eps_slip: float = 1.0,
    c_st: float = 0.0,
    k_xc: float = 0.0,
    s_comp: float = 0.0,
) -> dict:
    """Inverse of :func:`lattice_from_continuum`: ``{"k_l", "k_s", "A_g", "k4", "k6",
    "tau_f", "gamma_f", "T_s", "eps_s", "c_st", "k_x", "s_comp"}``."""
    s0 = fibre_frame(angles_deg)[0]
    cell = s0 * spacing**2
    return {
        "k_l": k_e / s0,
        "k_s": k_sh / cell,
        "A_g": k_b / s0,
        "k4": k_sh4 / cell,
        "k6": k_sh6 / cell,
        "tau_f": m_shf / cell,
        "gamma_f": gamma_f,
        "T_s": f_slip / (s0 * spacing),
        "eps_s": eps_slip,
        "c_st": c_st,
        "k_x": k_xc / cell,
        "s_comp": s_comp,
    }
