"""The diagnosis's cheap starts (docs/speed.md, "After"): a candidate's refit started at the
linearised refit (fitting/start.py ``linearised_start``) ends where the refit from the best of
the log grid ends, to the fit's tolerance; a linearisation that does not hold is refused; the
reaction's sensitivity from the lifted weight (forward/tangent.py) equals the full matrix's;
a run at moduli stored earlier starts from that state (forward/warm_start.py), with the same
answer; runs shared among the ranks leave every rank the same stored runs.

Small on purpose (48 × 24 mm, h = 4 mm, one or two load steps): the fits take a few seconds."""

import logging

import numpy as np
import pytest
from mpi4py import MPI
from toy_forward import ToyForward

from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.diagnosis.ranking import gauss_newton_start, predicted_chi2
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.start import RHO_MIN, grid_start, linearised_start
from fabricsurf.inverse.forward import profile, ranks, tangent, warm_start
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import PROGRESS

COMM = MPI.COMM_WORLD
TRUTH = {
    "fibre_stretch": {"k_l": 25.0, "k_m": 25.0},
    "shear": {"k_s": 0.4},
    "geodesic_bending": {"A_g": 12.0},
}
BASE = {"fibre_stretch": {"k_l": 25.0, "k_m": 25.0}, "shear": {"k_s": 0.4}}
TOL = 1e-6
"""The fit's own stopping tolerance on χ² (fit.fit's default)."""


def data(path=(2.0,)):
    exp = sy.template(48.0, 24.0, list(path), sy.grid_points(48.0, 24.0, 8, 4))
    sy.continuum_data(exp, full_model(list(TRUTH), TRUTH), h=4.0)
    return sy.add_noise(exp, 0.005, 0.005, 31)


def indices(fm, terms) -> list[int]:
    return [i for i, (t, _) in enumerate(fm.params) if t.name in terms]


def test_the_linearised_start_refits_to_the_grid_starts_optimum():
    with ForwardModel(data(), full_model(list(BASE), BASE), h=4.0) as fm:
        free, idx = indices(fm, BASE), indices(fm, ["geodesic_bending"])
        cur = fit(fm, free, scale_start=False, space="linear")
        fm.set_values(cur.values)
        r, Jr = fm.residuals(fm.run(sens=True))
        gn = gauss_newton_start(r, Jr, cur.values, free, idx)
        predicted = predicted_chi2(r, Jr, cur.values, gn, free, idx)
        start, first, _ = linearised_start(fm, free, idx, gn, predicted, cur.chi2)
        assert start is not None and np.array_equal(start, gn)
        fm.set_values(start)
        lin = fit(fm, free + idx, scale_start=False, space="linear", first=first)
        fm.set_values(cur.values)  # the grid without the linearised start: another start
        start, first = grid_start(fm, cur.values, free, idx, 0.0, cur.chi2, [], free + idx)
        assert not np.array_equal(start, gn)
        fm.set_values(start)
        grid = fit(fm, free + idx, scale_start=False, space="linear", first=first)
    assert abs(lin.chi2 - grid.chi2) <= TOL * grid.chi2
    # χ² within TOL of each other: the moduli within sqrt(TOL·χ²) statistical deviations
    dev = np.abs(lin.values - grid.values)[free + idx] / grid.std[free + idx]
    assert np.all(dev <= np.sqrt(TOL * grid.chi2)), dev
    assert lin.forward_runs <= grid.forward_runs  # the check run counted once in each


def test_a_linearisation_that_does_not_hold_is_refused():
    with ForwardModel(data(), full_model(list(TRUTH), TRUTH), h=4.0) as fm:
        free, idx = indices(fm, BASE), indices(fm, ["geodesic_bending"])
        cur = fm.values()
        chi2 = float(np.sum(fm.residuals(fm.run())[0] ** 2))
        # a start that raises χ², against a prediction of a large decrease
        worse = cur.copy()
        worse[idx] *= 3.0
        start, first, note = linearised_start(fm, free, idx, worse, 0.0, chi2)
        assert start is None and first is None and f"at least {RHO_MIN}" in note
        worse[idx] = 0.0  # the linearisation wants no candidate: no start, no run
        runs = fm.forward_runs
        assert linearised_start(fm, free, idx, worse, 0.0, chi2)[0] is None
        assert fm.forward_runs == runs


def test_the_lifted_weight_gives_the_full_matrixs_reaction_sensitivity():
    exp = data((1.0, 2.0))
    out = {}
    old = tangent.SYMMETRIC
    try:
        for symmetric in (False, True):
            tangent.SYMMETRIC = symmetric
            with ForwardModel(exp, full_model(list(TRUTH), TRUTH), h=4.0) as fm:
                out[symmetric] = fm.run(sens=True)
    finally:
        tangent.SYMMETRIC = old
    full, lifted = out[False].dforce, out[True].dforce
    assert np.max(np.abs(lifted - full)) <= 1e-12 * np.max(np.abs(full))
    assert np.array_equal(out[False].du, out[True].du)


def test_a_run_at_stored_moduli_starts_from_that_state():
    exp = data((1.0, 2.0))
    with ForwardModel(exp, full_model(list(TRUTH), TRUTH), h=4.0) as fm:
        p1 = fm.values()
        first = fm.run(sens=True)
        fm.set_values(p1 * 3.0 + 1.0)  # far away: cold
        fm.run()
        fm.set_values(p1)
        again = fm.run(sens=True)
        with ForwardModel(exp, full_model(list(TRUTH), TRUTH), h=4.0) as cold:
            reference = cold.run()
    steps = len(exp.path)
    assert first.newton > 2 * steps and again.newton <= 2 * steps  # 1–2 per step: warm
    assert len(warm_start.of(fm).runs) == 3 if warm_start.ENABLED else True
    scale = np.max(np.abs(reference.u))
    assert np.max(np.abs(again.u - reference.u)) <= 1e-8 * scale
    assert np.max(np.abs(again.force - reference.force)) <= 1e-8 * np.max(np.abs(reference.force))
    assert np.max(np.abs(again.du - first.du)) <= 1e-6 * np.max(np.abs(first.du))


@pytest.mark.skipif(COMM.size == 1, reason="needs several ranks")
def test_shared_runs_leave_every_rank_the_same_stored_runs():
    with ForwardModel(data(), full_model(list(TRUTH), TRUTH), h=4.0) as fm:
        p = fm.values()
        trials = [p * f for f in (0.5, 1.0, 2.0, 4.0)[: 2 * COMM.size]]

        def chi2(v):
            fm.set_values(v)
            return float(np.sum(fm.residuals(fm.run())[0] ** 2))

        ranks.spread(fm, trials, chi2)
        stored = [run["p"] for run in warm_start.of(fm).runs]
        assert len(stored) == len(trials)
        every = COMM.allgather(stored)
        assert all(len(s) == len(stored) for s in every)
        assert all(np.array_equal(a, b) for s in every for a, b in zip(s, stored))


def test_the_profile_counts_each_stages_runs_and_estimates_the_rest():
    prof = profile.Profile()
    with ForwardModel(data(), full_model(list(TRUTH), TRUTH), h=4.0) as fm:
        with profile.active(prof):
            with prof.stage("baseline fit", say=False):
                fm.run()
                with prof.stage("round 1: ranking", say=False):
                    pred = fm.run(sens=True)
        fm.run()  # not recorded: no profile active
    out = prof.as_json()
    assert [(q["stage"], q["forward_runs"]) for q in out["stages"]] == [
        ("baseline fit", 1),
        ("round 1: ranking", 1),
    ]
    assert out["stages"][1]["newton"] == pred.newton and out["forward_runs"] == 2
    assert out["seconds"] >= sum(q["seconds"] for q in out["stages"])
    mine = {name: row["seconds"] for (_, name), row in prof.rows.items()}  # this rank's
    assert prof.estimate_left(["round 2: ranking"]) == pytest.approx(mine["round 1: ranking"])
    assert prof.estimate_left(["h/2 check"]) == pytest.approx(
        profile.RELATIVE["h/2 check"] * mine["baseline fit"]
    )


def test_the_profile_says_the_stage_and_the_time_left(caplog):
    prof = profile.Profile()
    caplog.set_level(logging.DEBUG, logger="fabricsurf.inverse.forward.profile")
    with prof.stage("baseline fit", level=1):
        with profile.stage("not recorded: no profile active"):
            pass
        with profile.active(prof), profile.stage("ranking"):
            pass
    assert list(prof.rows) == [(1, "baseline fit"), (1, "ranking")]
    prof.progress(1, "round 1: ranking", ["round 1: ranking", "h/2 check"])
    said = [r.getMessage() for r in caplog.records]
    if COMM.rank == 0:
        assert said[0].startswith("[level 1] baseline fit (")
        assert said[1].startswith("[level 1] round 1: ranking: ") and "s left" in said[1]
    else:
        assert said == []


def test_a_refits_optimum_is_kept_while_later_runs_come():
    with ForwardModel(data(), full_model(list(TRUTH), TRUTH), h=4.0) as fm:
        ws = warm_start.of(fm)
        if not ws.enabled:
            return
        fake = {"u": [np.zeros(3)], "du": {}}
        ws.runs = [{"p": np.full(3, float(k)), **fake} for k in range(warm_start.KEEP)]
        ws.latest(np.full(3, 2.0))
        for k in range(warm_start.KEEP):  # as many runs again: all the old ones go but one
            ws.store({"p": np.full(3, 100.0 + k), **fake})
        kept = [float(r["p"][0]) for r in ws.runs]
        assert (
            len(kept) == warm_start.KEEP
            and kept[0] == 2.0
            and kept[1:] == [100.0 + k for k in range(1, warm_start.KEEP)]
        )


def test_the_latest_run_with_sensitivities_is_kept_while_later_runs_come():
    with ForwardModel(data(), full_model(list(TRUTH), TRUTH), h=4.0) as fm:
        ws = warm_start.of(fm)
        if not ws.enabled:
            return
        ws.store({"p": np.full(3, -1.0), "u": [np.zeros(3)], "du": {0: [np.ones(3)]}})
        for k in range(warm_start.KEEP + 2):
            ws.store({"p": np.full(3, float(k)), "u": [np.zeros(3)], "du": {}})
        kept = [float(r["p"][0]) for r in ws.runs]
        assert len(kept) == warm_start.KEEP and kept[0] == -1.0 and kept[-1] == warm_start.KEEP + 1


@pytest.mark.skipif(COMM.size == 1, reason="needs several ranks")
def test_a_scout_built_inside_shared_refits_is_a_clear_error_on_every_rank():
    """Building a model is collective: one rank building a scout inside evaluations shared
    among the ranks hung both (a refit whose linearised start failed ranked a grid on a scout
    that did not exist yet). It is refused with a message, raised on every rank by spread, and
    the diagnosis's rounds build the scout before they share their refits."""
    with ForwardModel(data(), full_model(list(TRUTH), TRUTH), h=4.0) as fm:

        def needs_scout(k: int) -> float:
            if k == COMM.size - 1:  # one rank only
                fm.coarse()
            return float(k)

        with pytest.raises(RuntimeError, match="cannot be built inside evaluations shared"):
            ranks.spread(fm, list(range(COMM.size)), needs_scout)
        assert fm._coarse is None
        fm.coarse()  # outside: built on every rank
        assert ranks.spread(fm, list(range(COMM.size)), needs_scout) == list(range(COMM.size))


class TwoWells(ToyForward):
    """A one-modulus toy fit (θ = log k, started at k = 2): on the fit's mesh χ² has its
    optimum at k = 1 and a higher local well (χ² = ``c``) at k = ``wrong``; the scout mesh has
    only the wrong well, as a scout whose discretisation error outweighs the data's noise
    ranks starts."""

    def __init__(self, wrong: float, c: float, scout=None):
        super().__init__(["a.k"], [2.0], COMM, scout)
        self.t2, self.c = np.log(wrong), c

    def residuals(self, pred):
        t, k = np.log(pred[0]), pred[0]
        if self.scout is not None and t * t <= (t - self.t2) ** 2 + self.c:
            return np.array([t, 0.0]), np.array([[1.0 / k], [0.0]])
        return np.array([t - self.t2, np.sqrt(self.c)]), np.array([[1.0 / k], [0.0]])


def test_scanned_start_checked_on_the_fit_mesh(caplog):
    """The decade scan ranks starts on the scout mesh; a scout that prefers a wrong well (a
    forming run coarser than the die's lip prefers soft yarns: docs/forming.md) sends the fit
    there unless the scanned start is checked against the given one on the fit's own mesh,
    where the given start (k = 2) fits better than the scanned one (k = 0.002): the fit starts
    from the given moduli, says so, and ends at the optimum k = 1, not in the wrong well."""
    fm = TwoWells(1e-3, 5.0, scout=TwoWells(1e-3, 0.0))
    caplog.set_level(PROGRESS, logger="fabricsurf")
    res = fit(fm)
    assert np.isclose(res.values[0], 1.0, rtol=1e-3), res.values
    if COMM.rank == 0:
        assert "start after the scale scan: a.k = 0.002" in caplog.text
        assert "the given moduli fit better on this mesh than the scanned start" in caplog.text
