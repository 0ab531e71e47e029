"""The kinematic drape from given generators over any surface
(fabricsurf/verification/drapes/tool_drape.py), the check of demos/demo_double_dome.py; the
forming run it checks is the demo's (tests/test_demos.py).

* Closed quadrant by quadrant from the geodesic generators of surface_drape.drape, the net is
  that drape's net, node for node, to round-off (on the analytic sphere and cylinder): the
  quadrants do not depend on each other's generators.
* With one generator half cut short, the two quadrants it bounds stop at its length and the
  other two are unchanged.
* The chords cut from a finely sampled curve on the sphere are a long each (to the samples'
  spacing squared) and lie on it; a curve that leaves the surface ends them instead of
  looping.
* A node is compared only if its whole rectangle back to the seed lies on the tool.

All of it is numpy: the 2-rank session skips it.
"""

import numpy as np
import pytest

from fabricsurf.experiments.forming.surfaces.analytic import Cylinder, Sphere
from fabricsurf.verification.drapes import surface_drape, tool_drape

pytestmark = pytest.mark.serial("numpy only: nothing here depends on the ranks")
A, N = 2.0, 8


def _generators(net: surface_drape.SurfaceNet) -> list[np.ndarray]:
    """The four halves (L+, L−, M+, M−) of a net's generators, from the seed outwards."""
    n = net.n
    return [net.x[n:, n], net.x[n::-1, n], net.x[n, n:], net.x[n, n::-1]]


@pytest.mark.parametrize(
    "surface, seed",
    [(Sphere(40.0), (0.0, 0.0, 40.0)), (Cylinder(30.0, axis=(1.0, 0.0, 0.0)), (0.0, 0.0, 30.0))],
)
@pytest.mark.parametrize("angles", [(0.0, 90.0), (30.0, -40.0)])
def test_quadrants_from_geodesic_generators_are_the_drape(surface, seed, angles):
    net = surface_drape.drape(surface, seed, A, N, angles)
    x, n = tool_drape._quadrants(surface, _generators(net), A)
    assert n == N
    assert np.abs(x - net.x).max() < 1e-11 * 40.0


def test_a_short_generator_half_shortens_only_its_quadrants():
    surface = Sphere(40.0)
    net = surface_drape.drape(surface, (0.0, 0.0, 40.0), A, N, (0.0, 90.0))
    gens = _generators(net)
    gens[1] = gens[1][:4]  # L backwards: 3 chords
    x, n = tool_drape._quadrants(surface, gens, A)
    assert n == N
    assert np.abs(x[N:, N:] - net.x[N:, N:]).max() < 1e-11 * 40.0  # (+, +) untouched
    assert np.abs(x[N:, : N + 1] - net.x[N:, : N + 1]).max() < 1e-11 * 40.0  # (+, −)
    short = x[: N + 1, N:]  # (−, +): i = −3 .. 0, j = 0 .. 3 (the row i = 0 is (+, +)'s too)
    assert np.isfinite(short[N - 3 :, :4]).all()
    assert np.abs(short[N - 3 :, :4] - net.x[N - 3 : N + 1, N : N + 4]).max() < 1e-11 * 40.0
    assert np.isnan(short[: N - 3]).all() and np.isnan(short[N - 3 : N, 4:]).all()


def test_chords_are_a_long_on_the_surface_and_end_where_the_curve_leaves_it():
    """Each node is interpolated along the straight segment between two samples and projected
    back: its chord errs by O(δ²/R), δ the samples' spacing, falling at rate 2 with δ."""
    surface = Sphere(40.0)
    errors = []
    for samples in (1001, 2001):
        t = np.linspace(0.0, 1.2, samples)
        p = 40.0 * np.column_stack([np.sin(t), 0.0 * t, np.cos(t)])
        nodes = tool_drape.chords(surface, p, A)
        assert len(nodes) == int(1.2 // (2.0 * np.arcsin(A / 80.0))) + 1  # the arc's chords
        assert np.abs(np.linalg.norm(nodes, axis=1) - 40.0).max() < 1e-12
        errors.append(np.abs(np.linalg.norm(np.diff(nodes, axis=0), axis=1) - A).max())
        delta = 40.0 * (t[1] - t[0])
        assert errors[-1] < delta**2 / (8.0 * 40.0)
    assert 3.0 < errors[0] / errors[1] < 5.0, errors
    # a curve that leaves the surface along its normal: every node projects back onto the
    # last one, and the chords end there instead of looping
    off = np.column_stack([0.0 * t, 0.0 * t, 40.0 + 10.0 * t])
    assert len(tool_drape.chords(surface, off, A)) == 1


def test_a_node_counts_only_with_its_rectangle_back_to_the_seed_on_the_tool():
    n = 3
    on = np.ones((2 * n + 1, 2 * n + 1), bool)
    on[n + 1, n + 2] = False  # one node of the (+, +) quadrant off the tool
    ok = tool_drape._reachable(on, n)
    assert not ok[n + 1 :, n + 2 :].any()  # everything beyond it in that quadrant
    assert ok[n + 1 :, n : n + 2].all() and ok[n, n:].all()
    assert ok[:, : n + 1].all() and ok[: n + 1, :].all()  # the other quadrants
