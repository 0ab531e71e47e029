"""Effects beyond the vocabulary in the Hencky lattice (fabricsurf.network.couplings and the
compression-soft fibre springs): derivatives, the zero-parameter network, the continuum
densities the mapping of fabricsurf.network.hencky_moduli claims."""

import numpy as np
import pytest

from fabricsurf.network.hencky import hencky_lattice
from fabricsurf.network.hencky_moduli import continuum_from_lattice, lattice_from_continuum

K_L, K_S, A_G = 30.0, 0.5, 2.0
EFFECTS = {
    "shear_tension": {"c_st": 8.0},
    "crimp": {"k_x": 12.0},
    "compression_soft": {"s_comp": 0.7},
    "all": {"c_st": 8.0, "k_x": 12.0, "s_comp": 0.7},
}


def lattice(eps=1.0, angles=(45.0, -45.0), size=(4.0, 3.0), **kw):
    k = lattice_from_continuum(K_L, K_S, A_G, eps, angles, **kw)
    return hencky_lattice(size[0], size[1], eps, angles, **k)


def perturbed(lat, seed, amp=0.15):
    """A random placement: strains of ±20 % and angle changes of ~0.2 rad, both signs, so
    that the compression-soft springs sit on both sides of their kink."""
    rng = np.random.default_rng(seed)
    return lat.net.X * rng.uniform(0.9, 1.1) + rng.normal(0, amp * lat.spacing, lat.net.X.shape)


@pytest.mark.parametrize("name", list(EFFECTS))
def test_gradient_and_hessian_match_finite_differences(name):
    """Central differences with step h = 1e-6 mm on O(1) mm lengths: truncation O(h²·E''') and
    round-off O(1e-16·E/h) are both ~1e-9 relative to the forces, so a bound of 1e-6 leaves
    three decades and still fails any wrong term (those are O(1)). The piecewise fibre springs
    have a jump of E'' at l = l0: no spring of the random placement lies within h of it."""
    lat = lattice(**EFFECTS[name])
    net = lat.net
    x = perturbed(lat, seed=3)
    strain = net.lengths(x) / net.l0 - 1.0
    assert (strain < 0).any() and (strain > 0).any()
    assert np.abs(strain).min() > 1e-4  # no spring within the FD step of the kink
    q = x.ravel()
    g, H = net.gradient(q).ravel(), net.hessian(q).toarray()
    h = 1e-6
    fd_g, fd_H = np.empty_like(g), np.empty_like(H)
    for a in range(len(q)):
        e = np.zeros_like(q)
        e[a] = h
        fd_g[a] = (net.energy(q + e) - net.energy(q - e)) / (2 * h)
        fd_H[:, a] = (net.gradient(q + e).ravel() - net.gradient(q - e).ravel()) / (2 * h)
    assert np.abs(fd_g - g).max() / np.abs(g).max() < 1e-6
    assert np.abs(fd_H - H).max() / np.abs(H).max() < 1e-6
    assert np.abs(H - H.T).max() <= 1e-12 * np.abs(H).max()


def test_coupling_hessian_alone_matches_finite_differences():
    """The coupled elements' own Hessian (without the springs it is added to) against
    differences of their own gradient: a wrong cross term could hide under the springs."""
    lat = lattice(c_st=8.0, k_x=12.0)
    cp = lat.net.couplings
    x = perturbed(lat, seed=5)
    n = len(x)

    def grad(q):
        g = np.zeros((n, 2))
        ge = cp.element_gradients(q.reshape(-1, 2)).reshape(-1, 3, 2)
        np.add.at(g, cp.tri, ge)
        return g.ravel()

    He = cp.element_hessians(x)
    H = np.zeros((2 * n, 2 * n))
    dofs = (2 * cp.tri[:, :, None] + np.arange(2)).reshape(-1, 6)
    for d, h_el in zip(dofs, He):
        H[np.ix_(d, d)] += h_el
    q, h = x.ravel(), 1e-6
    fd = np.empty_like(H)
    for a in range(len(q)):
        e = np.zeros_like(q)
        e[a] = h
        fd[:, a] = (grad(q + e) - grad(q - e)) / (2 * h)
    assert np.abs(fd - H).max() / np.abs(H).max() < 1e-6
    assert np.abs(He - He.transpose(0, 2, 1)).max() <= 1e-12 * np.abs(He).max()


def test_zero_parameters_give_the_old_network_bitwise():
    old = hencky_lattice(4.0, 3.0, 1.0, k_e=2.0, k_sh=0.3, k_b=0.1)
    new = hencky_lattice(4.0, 3.0, 1.0, k_e=2.0, k_sh=0.3, k_b=0.1, c_st=0.0, k_xc=0.0, s_comp=0)
    assert new.net.couplings is None
    x = perturbed(old, seed=7)
    assert old.net.energy(x) == new.net.energy(x)
    assert np.array_equal(old.net.gradient(x), new.net.gradient(x))
    assert np.array_equal(old.net.hessian(x).toarray(), new.net.hessian(x).toarray())


@pytest.mark.parametrize("angles", [(45.0, -45.0), (40.0, -40.0)])
@pytest.mark.parametrize("F", [[[1.06, 0.12], [0.03, 0.97]], [[0.93, -0.2], [0.05, 1.08]]])
def test_affine_placement_gives_the_continuum_densities_exactly(angles, F):
    """Affine placement x = F X: every quadrant element's energy is a quarter cell times the
    continuum density and every fibre spring's a cell times it (hencky_moduli: arm strains
    are exactly λ−1, μ−1 and the quadrant angle changes ∓γ), for a stretch + shear that
    compresses one fibre family and stretches the other (F[0]) or both ways (F[1])."""
    eps, p = 0.7, {"c_st": 8.0, "k_x": 12.0, "s_comp": 0.7}
    lat = lattice(eps, angles, (6.0, 5.0), **p)
    net, F = lat.net, np.asarray(F)
    x = lat.net.X @ F.T
    FL, FM = F @ lat.L, F @ lat.M
    lam, mu = np.linalg.norm(FL), np.linalg.norm(FM)
    theta0 = np.arccos(lat.L @ lat.M)
    gamma = theta0 - np.arccos(FL @ FM / (lam * mu))
    s0 = np.sin(theta0)
    cell = eps**2 * s0
    assert lam < 1 or mu < 1

    def fibre(s):
        return 0.5 * K_L * (1 - p["s_comp"] * (s < 0)) * s**2

    shear = 0.5 * K_S * (1 + p["c_st"] * ((lam - 1) + (mu - 1))) * gamma**2
    crimp = p["k_x"] * (lam - 1) * (mu - 1)
    ee, er = net.spring_energies(x)
    sh, nl = lat.spring_sets["shear"], len(lat.spring_sets["stretch_l"])
    assert np.allclose(ee[:nl], cell * fibre(lam - 1), rtol=1e-12)
    assert np.allclose(ee[nl:], cell * fibre(mu - 1), rtol=1e-12)
    assert np.allclose(er[sh], cell / 4 * (shear + crimp), rtol=1e-10)
    # and the whole patch's energy per node area, interior plus boundary quadrants: the
    # density to the share of dropped quadrants (boundary), counted exactly here
    nq = len(sh)
    area = len(net.X) * cell
    dens = fibre(lam - 1) * nl / len(net.X) + fibre(mu - 1) * (len(ee) - nl) / len(net.X)
    dens += (shear + crimp) * nq / (4 * len(net.X))
    assert net.energy(x) / area == pytest.approx(dens, rel=1e-10)


def test_mapping_round_trip():
    k = lattice_from_continuum(K_L, K_S, A_G, 0.8, (40.0, -40.0), c_st=3.0, k_x=7.0, s_comp=0.4)
    back = continuum_from_lattice(spacing=0.8, angles_deg=(40.0, -40.0), **k)
    assert back["c_st"] == 3.0 and back["s_comp"] == 0.4
    assert back["k_x"] == pytest.approx(7.0, rel=1e-14)


def test_compression_soft_spring_force_is_piecewise_linear():
    lat = lattice(s_comp=0.75)
    net = lat.net
    i, j = net.ext[0]
    for s, k_eff in ((0.05, 1.0), (-0.05, 0.25)):
        x = net.X.copy()
        x[j] = x[i] + (1 + s) * (net.X[j] - net.X[i])
        t = net._ext_terms(x)[2][0]
        assert t == pytest.approx(k_eff * net.k_ext[0] * s * net.l0[0], rel=1e-12)
    with pytest.raises(ValueError, match="s_comp"):
        lattice(s_comp=1.0)
