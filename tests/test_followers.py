"""Step followers (fabricsurf/experiments/followers.py): the bi-pantographic interior penalty
follows the solution inside :meth:`BiasExtension.run` by default, with no callback."""

import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.evaluation import interpolate_expression
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.experiments.followers import PENALTY_MARGIN, PenaltyFollower, penalty_stretch
from fabricsurf.model.materials import PantographBending, bipantographic

LENGTH, WIDTH, H = 187.0, 119.0, 17.0
"""mm: the bias specimen on a coarse fibre-aligned mesh (the forms of the bias demo)."""


def small_test(model) -> BiasExtension:
    return BiasExtension(model, LENGTH, WIDTH, h=H, comm=MPI.COMM_WORLD)  # gradient clamps


def largest_stretch(test: BiasExtension) -> float:
    """max(λ, μ) over the DG2 nodes of all cells of all ranks."""
    kin = test.problem.energy.kin
    V = fem.VectorFunctionSpace(test.problem.msh, ("DG", 2), dim=2)
    f = interpolate_expression(ufl.as_vector([kin.lam, kin.mu]), V)
    return test.problem.msh.comm.allreduce(float(f.x.array.max()), op=MPI.MAX)


def penalty_range(term: PantographBending, test: BiasExtension) -> tuple[float, float]:
    """(min, max) over all ranks of ρ_p in the DG0 field of ``term`` in the test's energy."""
    a = test.problem.energy.constants_of(term)["penalty_stretch"].x.array
    comm = test.problem.msh.comm
    return comm.allreduce(float(a.min()), op=MPI.MIN), comm.allreduce(float(a.max()), op=MPI.MAX)


def test_penalty_follows_the_stretch_by_default():
    """After each step of a plain ``run`` the penalty stretch ρ_p of the bending term is
    max(1, min(ρ + margin, (ρ + 1/cos γ)/2)) of that step's largest fibre stretch ρ (the
    follower's rule), uniform over all cells of all ranks; as the specimen is pulled ρ grows,
    so ρ_p rises above its initial 1 and keeps rising (frozen at 1, the penalty of the
    bi-pantographic energy loses coercivity where the stretch concentrates); the term's own
    ``penalty_stretch`` follows. ``reset`` returns ρ_p, in the form and the term, to the
    term's value before the run."""
    test = small_test(bipantographic())
    bending = next(t for t in test.model if isinstance(t, PantographBending))  # the test's own
    assert [type(f) for f in test.followers] == [PenaltyFollower]
    seen, own = [], []

    def on_step(k: int, ubar: float) -> None:
        seen.append((largest_stretch(test), *penalty_range(bending, test)))
        own.append(bending.penalty_stretch)  # the term's own value follows its form's

    test.run(0.06 * LENGTH, 3, on_step=on_step)
    history = test.followers[0].history
    assert len(history) == len(seen) == 3
    for (rho, lo, hi), rec in zip(seen, history):
        expected = max(1.0, float(penalty_stretch(rho, PENALTY_MARGIN, bending.gamma)))
        assert lo == hi == pytest.approx(expected, rel=1e-12)
        assert rec["max_stretch"] == pytest.approx(rho, rel=1e-12)
        assert rec["rho_cos_gamma"] == pytest.approx(rho * math.cos(bending.gamma), rel=1e-12)
    rho_p = [lo for _, lo, _ in seen]
    assert rho_p[0] > 1.0 and np.all(np.diff(rho_p) > 0), seen
    assert own == rho_p
    test.followers[0].reset()
    assert penalty_range(bending, test) == (1.0, 1.0) and bending.penalty_stretch == 1.0


def test_an_empty_follower_list_freezes_the_penalty():
    """``followers = []`` leaves ρ_p at the term's value although the stretch grows."""
    test = small_test(bipantographic())
    bending = next(t for t in test.model if isinstance(t, PantographBending))  # the test's own
    test.followers = []
    test.run(0.06 * LENGTH, 1)
    assert largest_stretch(test) > 1.0
    assert penalty_range(bending, test) == (1.0, 1.0)
