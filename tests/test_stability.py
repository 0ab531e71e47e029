"""The stability check of an energy over the data's states (fabricsurf.model.stability): the
tangent ∂²W/∂(λ, μ, γ)² against its closed form, a signed coupling found unstable exactly where
its shear stiffness turns negative, built-in models stable, the states of a deformed mesh exact
for a homogeneous deformation, and 1 rank = 2 ranks."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.discretise.evaluation import fibre_states
from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.inverse.fitting.compare import compare
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.kinematics import fibre_vectors
from fabricsurf.model.stability import ROUND_OFF, check_tangent, path_states
from fabricsurf.model.term import Term
from fabricsurf.model.terms import EFFECTS, make_term
from fabricsurf.model.user_effects import register_effect

K_L, K_S = 30.0, 0.5


@dataclass
class Coupling(Term):
    """½k_c γ²((λ−1)+(μ−1)), k_c of either sign."""

    k_c: float = 1.0
    name: ClassVar[str] = "stability_test_coupling"
    units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}
    signed: ClassVar[tuple[str, ...]] = ("k_c",)

    def density(self, kin, p):
        return 0.5 * p["k_c"] * kin.gamma**2 * ((kin.lam - 1) + (kin.mu - 1))


def model(k_c: float) -> list[Term]:
    stretch = make_term("fibre_stretch", k_l=K_L, k_m=K_L)
    return [stretch, make_term("shear", k_s=K_S), Coupling(k_c)]


def closed_form(k_c: float, lam: float, mu: float, g: float) -> np.ndarray:
    """K of ½k_l(λ−1)² + ½k_l(μ−1)² + ½k_s γ² + ½k_c γ²(λ−1+μ−1)."""
    return np.array(
        [
            [K_L, 0.0, k_c * g],
            [0.0, K_L, k_c * g],
            [k_c * g, k_c * g, K_S + k_c * ((lam - 1) + (mu - 1))],
        ]
    )


def states(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(0.95, 1.1, n), rng.uniform(0.95, 1.1, n), rng.uniform(-0.8, 0.8, n)]
    )


@pytest.mark.parametrize("k_c", [-3.0, 2.0])
def test_smallest_eigenvalue_is_the_closed_forms(k_c):
    """The check's smallest eigenvalue and its state are those of the closed-form K over the
    same states, to round-off (W's derivatives are UFL's, exact)."""
    s = states(50)
    res = check_tangent(model(k_c), (45.0, -45.0), s)
    low = np.array([np.linalg.eigvalsh(closed_form(k_c, *q))[0] for q in s])
    assert res.states == len(s)
    assert res.min_eigenvalue == pytest.approx(low.min(), abs=1e-10 * K_L)
    assert np.allclose(res.worst, s[np.argmin(low)], rtol=0, atol=1e-14)
    assert res.stable == (low.min() >= -ROUND_OFF * res.largest)
    assert res.unstable_share == pytest.approx(np.mean(low < -ROUND_OFF * res.largest))


def test_negative_coupling_unstable_only_beyond_its_reach():
    """k_c = −3: the shear stiffness K_S + k_c(λ−1+μ−1) turns negative once the two stretches
    add up to more than K_S/3 = 0.167; the check is stable below and not above (γ = 0, where
    K is diagonal and the sign is that of the shear entry)."""
    below = np.array([[1.08, 1.08, 0.0]])  # 0.5 − 3·0.16 = 0.02 > 0
    above = np.array([[1.09, 1.09, 0.0]])  # 0.5 − 3·0.18 = −0.04 < 0
    assert check_tangent(model(-3.0), (45.0, -45.0), below).stable
    res = check_tangent(model(-3.0), (45.0, -45.0), above)
    assert not res.stable
    assert res.min_eigenvalue == pytest.approx(K_S - 3.0 * 0.18, rel=1e-10)
    assert "NOT stable" in res.text()


def test_builtin_models_stable_at_other_fibre_angles():
    """The built-ins with moduli ≥ 0 and the nonlinear shear locking are convex in (λ, μ, γ):
    stable over the whole range at ±40° fibres and at 0/90°."""
    m = [
        make_term("fibre_stretch", k_l=100.0, k_m=50.0),
        make_term("shear", k_s=0.3),
        make_term("shear_locking", k4=2.0),
    ]
    for angles in ((40.0, -40.0), (0.0, 90.0)):
        res = check_tangent(m, angles, path_states(states(40, seed=1)))
        assert res.stable and res.min_eigenvalue > -ROUND_OFF * res.largest


def test_states_of_a_homogeneous_deformation():
    """fibre_states of u = (F − I)X with F = λ l⊗L* + μ m⊗M* are (λ, μ, γ) in every cell."""
    angles, (lam, mu, g) = (40.0, -40.0), (1.05, 0.98, 0.3)
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 3, 2)
    L, M = fibre_vectors(*angles)
    a_l, a_m = (math.radians(a) for a in angles)
    s = math.copysign(1.0, math.sin(a_l - a_m))
    l_ = np.array([math.cos(a_l - s * g / 2), math.sin(a_l - s * g / 2)])
    m_ = np.array([math.cos(a_m + s * g / 2), math.sin(a_m + s * g / 2)])
    dual = np.linalg.inv(np.column_stack([L, M]))
    F = lam * np.outer(l_, dual[0]) + mu * np.outer(m_, dual[1])
    V = fem.VectorFunctionSpace(msh, ("CG", 1))
    u = fem.Function(V)
    u.interpolate(lambda x: (F - np.eye(2)) @ x[:2])
    got = fibre_states(u, ufl.as_vector(L), ufl.as_vector(M))
    assert got.shape[1] == 3 and len(got) == msh.topology.index_map(2).size_local
    assert np.allclose(got, [lam, mu, g], rtol=0, atol=1e-12)


def test_one_rank_equals_two():
    """Each rank checks its own half of the states; the reduced answer is that of all the states
    on one rank (the smallest eigenvalue, its state, the share)."""
    comm = MPI.COMM_WORLD
    s = states(60, seed=3)
    whole = check_tangent(model(-3.0), (45.0, -45.0), s)
    mine = np.array_split(s, comm.size)[comm.rank]
    split = check_tangent(model(-3.0), (45.0, -45.0), mine, comm=comm)
    assert split.min_eigenvalue == whole.min_eigenvalue
    assert split.worst == whole.worst
    assert split.states == whole.states and split.unstable_share == whole.unstable_share


@pytest.fixture
def registered():
    """The coupling registered as a user's effect for the test (forward models take
    registered effects only), unregistered after."""
    register_effect(Coupling)
    yield
    EFFECTS.unregister(Coupling.name)


def bias_test():
    """40 × 20 mm bias specimen pulled 2 and 4 mm: shear angles to ≈ 19°, stretches ≈ 2 %."""
    exp = sy.template(40.0, 20.0, [2.0, 4.0], sy.grid_points(40.0, 20.0, 4, 2))
    exp.noise_std, exp.force_noise_std = 0.01, 0.01
    return exp


def test_compare_reports_stability_of_a_signed_model(registered):
    """compare() of a model with a signed coupling carries the check of its energy over the
    states of its own predictions; a model without one carries None."""
    res = compare(bias_test(), model(2.0))
    assert res.stability is not None and res.stability.stable
    assert res.stability.states > 0 and "is stable" in res.stability.text()
    assert compare(bias_test(), model(2.0)[:2]).stability is None


def test_a_material_limit_point_is_named(registered):
    """k_c = −10: the coupling's tangent K_S + k_c(λ−1+μ−1) − 2(k_c γ)²/k_l turns negative
    before the last load, and the load path stops at a limit point no step cutting passes;
    the error says the energy lost stability there (not only that Newton did not converge)."""
    with pytest.raises(LoadStepError) as err:
        compare(bias_test(), model(-10.0))
    text = str(err.value)
    assert "did not converge" in text and "NOT stable" in text


def test_fit_of_a_signed_coupling(registered):
    """Data made with k_c = −3 on the fit's own mesh (no mesh bias), noise 0.005 mm and N:
    the fit starts the coupling at 0 (a log-scale modulus could not), steps it linearly,
    finds it negative with a 95 % interval that holds −3 and excludes 0, reports the
    coupling as itself in the intervals (no log), and the energy stable over the data."""
    exp = sy.template(40.0, 20.0, [1.0, 2.0, 3.0], sy.grid_points(40.0, 20.0, 8, 4))
    exp = sy.add_noise(sy.continuum_data(exp, model(-3.0), h=4.0), 0.005, 0.005, seed=1)
    start = [make_term("fibre_stretch", k_l=20.0, k_m=20.0), make_term("shear", k_s=1.0)]
    with ForwardModel(exp, [*start, Coupling(0.0)], h=4.0) as fm:
        res = fit(fm)
    saved = res.as_dict()
    k_c = saved["moduli"]["stability_test_coupling.k_c"]
    assert k_c["ci95"][0] < -3.0 < k_c["ci95"][1] < 0.0 and k_c["identifiable"]
    assert saved["stability"]["stable"] and saved["stability"]["states"] > 0
    assert res.undetermined == []
