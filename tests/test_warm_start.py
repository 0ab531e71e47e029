"""Warm starts of the forward runs (fabricsurf/inverse/forward/warm_start.py): a fit gives the
same moduli and χ² as with every load step started cold, to what Newton's tolerance allows,
with fewer Newton iterations; the load stepper falls back to the last converged state when
Newton fails from a predicted one.

The tolerance: a cold step stops at a residual of 1e-10 (absolute, or relative to its start's)
and then once a Newton correction is below 1e-8 of the state; a warm-started step on the
correction test alone (or the absolute residual). Two converged states differ by about the
last correction squared, or 1e-10 / k in displacement (k ≥ 0.4 N/mm here), i.e. ≤ 1e-9 mm,
2e-7 of the noise level: the residuals and their sensitivities agree to about that relative
precision, and a fit that takes the same steps ends at moduli and χ² that agree to well below
1e-6 (the fit's own stopping tolerance on χ² is 1e-6)."""

import logging

import numpy as np
from mpi4py import MPI

from fabricsurf.datasets import cao2008_plain_weave
from fabricsurf.discretise.snes import reason_name
from fabricsurf.discretise.stepping import LoadStepper
from fabricsurf.inverse.contract.data import load_experiment
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward import warm_start
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.terms import FibreStretch, Shear, parse_terms
from fabricsurf.studies import woven as wv

TRUTH = {
    "fibre_stretch": {"k_l": 25.0, "k_m": 25.0},
    "shear": {"k_s": 0.4},
    "geodesic_bending": {"A_g": 12.0},
}
START = {
    "fibre_stretch": {"k_l": 20.0, "k_m": 30.0},
    "shear": {"k_s": 0.5},
    "geodesic_bending": {"A_g": 8.0},
}


def one_fit(exp, warm: bool):
    """A fit from START, the forward runs warm-started or not: (result, Newton iterations of
    each forward run)."""
    old = warm_start.ENABLED
    warm_start.ENABLED = warm
    try:
        with ForwardModel(exp, full_model(list(TRUTH), START), h=4.0) as fm:
            newton = []
            run = fm.run

            def counted(*a, **k):
                pred = run(*a, **k)
                newton.append(pred.newton)
                return pred

            fm.run = counted
            free = [i for i, (t, _) in enumerate(fm.params) if t.name in TRUTH]
            res = fit(fm, free, scale_start=False, space="linear")
            return res, newton
    finally:
        warm_start.ENABLED = old


def test_warm_fit_equals_cold_fit_with_fewer_newton_iterations():
    exp = sy.template(48.0, 24.0, [2.0], sy.grid_points(48.0, 24.0, 8, 4))
    sy.continuum_data(exp, full_model(list(TRUTH), TRUTH), h=4.0)
    sy.add_noise(exp, 0.005, 0.005, 31)
    cold, n_cold = one_fit(exp, False)
    warm, n_warm = one_fit(exp, True)
    print("cold", cold.values[cold.free], cold.chi2, n_cold)
    print("warm", warm.values[warm.free], warm.chi2, n_warm)
    assert len(n_warm) == len(n_cold) and cold.iterations == warm.iterations
    free = cold.free
    assert np.allclose(warm.values[free], cold.values[free], rtol=1e-7, atol=0.0)
    assert abs(warm.chi2 - cold.chi2) <= 1e-8 * cold.chi2
    assert np.allclose(warm.std[free], cold.std[free], rtol=1e-6)
    # the first run is cold in both; then each step starts from the last run's, corrected by
    # the sensitivities: fewer iterations, and at the optimum's small steps two instead of four
    assert n_warm[0] == n_cold[0] and sum(n_warm) < sum(n_cold)
    assert n_warm[-1] <= 0.5 * n_cold[-1]
    same = MPI.COMM_WORLD.allgather((n_warm, float(warm.chi2)))
    assert all(x == same[0] for x in same)


class Stub:
    """Converges from any start within ``basin`` of the load's solution u = t, else fails."""

    def __init__(self, basin: float):
        self.basin, self.t = basin, 0.0
        self.u = type("U", (), {"x": type("X", (), {"array": np.zeros(1)})()})()

    def state(self):
        return [self.u.x.array.copy()]

    def restore(self, state):
        self.u.x.array[:] = state[0]

    def set(self, t):
        self.t = t

    def solve(self, near: bool = False):
        if abs(self.u.x.array[0] - self.t) <= self.basin:
            self.u.x.array[:] = self.t
            return 2, 1
        return -5, 25


def test_stepper_uses_a_good_prediction_and_falls_back_from_a_bad_one(caplog):
    s = Stub(basin=1.5)
    stepper = LoadStepper(s, s.set, predictor=lambda k, t: np.array([t + 0.1]))
    assert stepper.run([1.0, 2.0, 3.0]) == [1, 1, 1]
    assert stepper.predicted == [True, True, True] and stepper.attempts == [1, 1, 1]
    s = Stub(basin=1.5)
    caplog.set_level(logging.DEBUG, logger="fabricsurf.discretise.stepping")
    stepper = LoadStepper(s, s.set, predictor=lambda k, t: np.array([t + 10.0]))
    assert stepper.run([1.0, 2.0]) == [26, 26]  # the failed start's 25, then one from u_k−1
    assert stepper.predicted == [False, False] and s.u.x.array[0] == 2.0
    logged = [r.getMessage() for r in caplog.records]
    assert logged[0].startswith("step 1: SNES DIVERGED_MAX_IT (-5) from the predicted state")
    stepper = LoadStepper(s, s.set, predictor=lambda k, t: None)
    s.u.x.array[:] = 0.0
    assert stepper.run([1.0]) == [1] and stepper.predicted == [None]


def _solves(fm, warm: bool) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """One run of ``fm`` (warm-started or not): its force, and (reason, Newton iterations) of
    every SNES solve the run made, failed attempts included."""
    sol, solves = fm.test.solver, []
    newton = sol._newton

    def recorded(near: bool = False):
        reason, its = newton(near)
        solves.append((reason_name(reason), its))
        return reason, its

    sol._newton = recorded
    try:
        if not warm:
            warm_start.forget(fm)
        return np.asarray(fm.run().force), solves
    finally:
        sol._newton = newton


def test_a_warm_start_at_the_rounding_floor_ends_by_the_correction_test():
    """The real fabric's model in the woven demo's size profile: yarns 3·10⁷ times stiffer than
    the shear (its penalty for inextensible yarns) and fibre bending. The residual's rounding
    floor (about 2e-8 here) lies above 1e-10 of a good warm start's residual, so a test
    relative to the start's can never pass: such steps ran to SNES's 25 iterations and were
    then followed again cold (warm runs took more Newton iterations than cold ones). A warm
    step must end by the correction test, in a few iterations, at the cold run's force: both
    stop where a correction is below 1e-8 of the state, so the forces agree to about that."""
    exp = wv.up_to_angle(load_experiment(cao2008_plain_weave()), 60.0)
    params = {
        "fibre_stretch": {"k_l": 6e5, "k_m": 6e5},
        "shear": {"k_s": 0.0185},
        "crossover_friction": {"tau_f": 0.00243},
        "geodesic_bending": {"A_g": 0.6},  # the size profile's first length, about h/2
    }
    with ForwardModel(exp, parse_terms(",".join(params), params), h=11.5) as fm:
        fm.run()
        vals = fm.values()
        vals[fm.names.index("shear.k_s")] *= 1.01
        fm.set_values(vals)
        f_warm, warm = _solves(fm, warm=True)
        f_cold, cold = _solves(fm, warm=False)
    assert len(warm) == len(exp.path)  # no warm start failed and was followed again cold
    assert {r for r, _ in warm} == {"CONVERGED_SNORM_RELATIVE (4)"}
    assert max(its for _, its in warm) <= 5  # quadratic from 1 % of the moduli away (cold: 5-8)
    assert sum(its for _, its in warm) < 0.75 * sum(its for _, its in cold)  # 122 against 210
    assert np.max(np.abs(f_warm - f_cold)) <= 1e-8 * np.max(np.abs(f_cold))


def test_a_forward_model_of_another_model_starts_from_the_carried_states():
    """The search beyond the vocabulary builds a new forward model on the diagnosis's mesh,
    its final terms with one more at zero: seeded with the final run's states
    (warm_start.carry, seed: moduli mapped by name) its first run takes one Newton iteration a
    step (the forced one) where a cold run takes more, and gives the same prediction. A
    carried run whose model has a modulus the new one lacks that is not zero is not used."""
    exp = sy.template(48.0, 24.0, [1.0, 2.0], sy.grid_points(48.0, 24.0, 8, 4))
    sy.continuum_data(exp, full_model(list(TRUTH), TRUTH), h=4.0)
    sy.add_noise(exp, 0.005, 0.005, 31)  # residuals of order one, in noise units
    with ForwardModel(exp, full_model(list(TRUTH), TRUTH), h=4.0) as fm:
        fm.run(sens=True)
        carried = warm_start.carry(fm, fm.values())
        lacking = warm_start.carry(fm, fm.values())
    more = full_model([*TRUTH, "shear_gradient"], {**TRUTH, "shear_gradient": {"A_Gamma": 0.0}})
    runs = {}
    for name, seed in (("cold", None), ("seeded", carried)):
        with ForwardModel(exp, more, h=4.0) as fm:
            if seed is not None:
                warm_start.seed(fm, seed)
            pred = fm.run()
            runs[name] = (pred.newton, fm.residuals(pred)[0])
    fewer = [FibreStretch(**TRUTH["fibre_stretch"]), Shear(**TRUTH["shear"])]
    with ForwardModel(exp, fewer, h=4.0) as fm:
        warm_start.seed(fm, lacking)  # geodesic_bending.A_g = 12 in the carried run
        assert not fm.__dict__.get("_warm_start") or not warm_start.of(fm).runs
    diff = np.abs(runs["seeded"][1] - runs["cold"][1]).max()
    print({k: v[0] for k, v in runs.items()}, diff, np.abs(runs["cold"][1]).max())
    assert runs["seeded"][0] == 2 and runs["cold"][0] > 2  # one forced iteration per step
    assert diff < 1e-7  # Newton's tolerance: 2e-7 of the noise level (module docstring)
