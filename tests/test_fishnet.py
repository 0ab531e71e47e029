"""The kinematic drape reference (fabricsurf/verification/drapes/fishnet.py) of a hemisphere.

Checks that can fail independently of each other:
* every net edge has length a and every node is on the sphere (the construction's two
  constraints, to round-off);
* the nodal shear on the generators is zero (the net is mirror-symmetric about each of them);
* the drape of a ±45° net is the 0/90° drape turned by 45°: its profile along the blank's x axis
  (the fibres' bisector) is the 0/90° diagonal profile, its diagonal (a fibre) carries no shear;
* the diagonal shear converges at rate 2 to the Chebyshev net of Hazzidakis' equation, solved
  on its own grid without the sphere's embedding (the limit a → 0 of the fishnet), and near
  the pole it is γ ≈ K u v (the equation linearised, K = 1/R²);
* a net is fixed by any two of its fibres through a node (Hazzidakis 1879): the fishnet's
  fibres through a node off the pole, not geodesics, sampled densely off the sphere and read
  as the generator drape reads a continuum's (generator_drape.chord_nodes), close back to the
  fishnet's own nodes.
"""

import itertools
import math

import numpy as np
import pytest

from fabricsurf.verification.drapes.fishnet import (
    chebyshev_shear,
    close_net,
    drape,
    edge_lengths,
    line_profile,
    node_shear,
)
from fabricsurf.verification.drapes.generator_drape import chord_nodes

R = 100.0


@pytest.fixture(scope="module")
def net():
    return drape(R, 5.0, 28)


def test_edges_and_sphere(net):
    assert np.abs(edge_lengths(net) - 5.0).max() < 1e-10
    assert np.abs(np.linalg.norm(net.x, axis=-1) - R).max() < 1e-10 * R


def test_generators_unsheared(net):
    g = node_shear(net)
    c = net.n - 1
    assert np.abs(g[:, c]).max() < 1e-12 and np.abs(g[c, :]).max() < 1e-12
    assert g[c + 5, c + 5] > 0.01  # the sheet does shear off the generators


def test_rotated_fibres(net):
    turned = drape(R, 5.0, 28, (45.0, -45.0))
    s0, g0 = line_profile(net, 45.0)
    s1, g1 = line_profile(turned, 0.0)
    assert len(s0) > 10 and len(s0) == len(s1)
    assert np.abs(s0 - s1).max() < 1e-9 * R and np.abs(g0 - g1).max() < 1e-12
    _, along_fibre = line_profile(turned, 45.0)
    assert len(along_fibre) == 0  # no cell centre on a fibre line: use the nodes instead
    c = turned.n - 1
    assert np.abs(node_shear(turned)[c:, c]).max() < 1e-12


def chebyshev_reference(u: float) -> float:
    """γ(u, u) of the Chebyshev net, Richardson-extrapolated from 60 and 120 steps (box scheme,
    second order)."""
    return (4 * chebyshev_shear(R, u, u, 120) - chebyshev_shear(R, u, u, 60)) / 3


def test_converges_to_chebyshev_net():
    u = 80.0  # the diagonal node (u/a, u/a), at a polar angle of about 0.6 rad
    ref = chebyshev_reference(u)
    errors = []
    for a in (10.0, 5.0):
        m = round(u / a)
        errors.append(abs(node_shear(drape(R, a, m + 1))[2 * m, 2 * m] - ref))
    rate = math.log2(errors[0] / errors[1])
    assert rate > 1.9, (errors, rate)
    assert errors[1] < 1e-3 * ref


def test_chebyshev_solver():
    """The box scheme converges at rate 2, and near the pole γ = K u v to leading order."""
    g = [chebyshev_shear(R, 60, 60, n) for n in (20, 40, 80)]
    assert math.log2(abs(g[0] - g[1]) / abs(g[1] - g[2])) > 1.9
    small = chebyshev_shear(R, 2.0, 2.0, 20)
    assert abs(small - 4.0 / R**2) < 1e-3 * small


def test_a_net_is_closed_from_any_two_of_its_fibres():
    a, n, m, angles = 5.0, 20, 12, (30.0, 120.0)
    big = drape(R, a, n, angles)
    c = (n + 3, n - 2)  # the node (3, −2): its fibres are not great circles

    def fibre(f: int, s: int) -> np.ndarray:
        k = c[f] + s * np.arange(m + 1)
        nodes = big.x[k, c[1]] if f == 0 else big.x[c[0], k]
        t = np.linspace(0.0, 1.0, 9)[:-1, None]
        dense = np.concatenate(
            [(1 - t) * p + t * q for p, q in itertools.pairwise(nodes)] + [nodes[-1:]]
        )
        return chord_nodes(0.999 * dense, R, a, m)  # below the sphere: projected back

    net = close_net(R, a, angles, {(f, s): fibre(f, s) for f in (0, 1) for s in (1, -1)})
    window = big.x[c[0] - m : c[0] + m + 1, c[1] - m : c[1] + m + 1]
    assert np.abs(net.x - window).max() < 1e-9 * R
    assert np.abs(node_shear(net)[m - 1]).max() > 0.02  # sheared along a generator
