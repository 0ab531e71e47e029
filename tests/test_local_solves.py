"""Rank-local forward solves (fabricsurf/inverse/forward/ranks.py): a small mesh solved whole on
every rank gives the distributed solve's fit (the same problem: equal to Newton's tolerance,
asserted at 1e-7 relative; the fit's own steps are taken on numbers the ranks agree on bit for
bit, and a repeated fit repeats them bit for bit), the ranks compute alike (no run needed rank
0's values), an error on one rank is the same error on all, and the candidate's trials shared
among the ranks give the serial choice. Serially the models solve on the one rank (nothing to
test but that)."""

import contextlib
import logging

import numpy as np
import pytest
from mpi4py import MPI

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.start import candidate_start
from fabricsurf.inverse.forward import ranks as local
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy

COMM = MPI.COMM_WORLD
TRUTH = {
    "fibre_stretch": {"k_l": 25.0, "k_m": 25.0},
    "shear": {"k_s": 0.4},
    "geodesic_bending": {"A_g": 12.0},
}
START = {"fibre_stretch": {"k_l": 10.0, "k_m": 10.0}, "shear": {"k_s": 1.0}}
parallel = pytest.mark.skipif(COMM.size == 1, reason="needs several ranks")


def data():
    exp = sy.template(48.0, 24.0, [1.0, 2.0], sy.grid_points(48.0, 24.0, 8, 4))
    sy.continuum_data(exp, full_model(list(TRUTH), TRUTH), h=4.0)
    return sy.add_noise(exp, 0.005, 0.005, 33)


def free_of(fm, terms) -> list[int]:
    return [i for i, (t, _) in enumerate(fm.params) if t.name in terms]


def same_on_all_ranks(a: np.ndarray) -> bool:
    return all(np.array_equal(a, b) for b in COMM.allgather(a))


def test_small_meshes_are_solved_whole_on_every_rank():
    exp = data()
    with ForwardModel(exp, full_model(["fibre_stretch", "shear"], START), h=4.0) as fm:
        assert fm.local == (COMM.size > 1)
        assert fm.test.problem.msh.comm.size == 1
    with ForwardModel(exp, full_model(["fibre_stretch", "shear"], START), h=4.0, local=False) as fm:
        assert not fm.local and fm.test.problem.msh.comm.size == COMM.size
    cells = local.estimated_cells(exp.setup.length, exp.setup.width, 0.5)
    assert cells > local.LOCAL_CELLS  # the default decides by the estimate
    assert local.solve_comm(COMM, cells) is COMM


def test_the_threshold_can_be_set_in_the_environment(monkeypatch):
    small = local.estimated_cells(48.0, 24.0, 4.0)
    monkeypatch.setenv(local.ENVIRONMENT, "0")
    assert local.solve_comm(COMM, small) is COMM
    monkeypatch.setenv(local.ENVIRONMENT, "1e9")
    assert local.solve_comm(COMM, 1e6) is (MPI.COMM_SELF if COMM.size > 1 else COMM)
    monkeypatch.setenv(local.ENVIRONMENT, "many")
    with (
        pytest.raises(ValueError, match="FABRICSURF_LOCAL_CELLS='many'")
        if COMM.size > 1
        else contextlib.nullcontext()
    ):
        local.solve_comm(COMM, small)


@parallel
def test_rank_local_fit_equals_the_distributed_fit_and_repeats_bit_for_bit():
    exp = data()
    out = []
    for mode in (False, True, True):
        with ForwardModel(
            exp,
            full_model(list(TRUTH), START | {"geodesic_bending": {"A_g": 3.0}}),
            h=4.0,
            local=mode,
        ) as fm:
            before = local.differed
            res = fit(fm, free_of(fm, TRUTH))
            out.append((res.values, res.misfit["chi2"], res.iterations, local.differed - before))
    (v_dist, chi2_dist, _, _), (values, chi2, its, differed), again = out
    assert np.allclose(values, v_dist, rtol=1e-7, atol=0)
    assert chi2 == pytest.approx(chi2_dist, rel=1e-7)
    assert same_on_all_ranks(values) and differed == 0
    # the same fit again: the same iterations and the same bits (serial solves, no
    # reduction whose order could vary between runs)
    assert its == again[2] and np.array_equal(values, again[0]) and chi2 == again[1]


@parallel
def test_an_error_on_rank_0_is_raised_on_every_rank():
    def run():
        if COMM.rank == 0:
            raise LoadStepError("step 2 failed on rank 0", step=2)
        return 1.0

    with pytest.raises(LoadStepError, match="failed on rank 0") as e:
        local.agree(COMM, True, run)
    assert e.value.step == 2


@parallel
def test_a_value_computed_differently_is_rank_0s_everywhere():
    before = local.differed
    value = local.agree(COMM, True, lambda: np.array([float(COMM.rank)]))
    assert value[0] == 0.0 and local.differed == before + 1


@parallel
def test_spread_trials_choose_the_start_the_serial_loop_chooses():
    exp = data()
    with ForwardModel(
        exp, full_model(list(TRUTH), START | {"geodesic_bending": {"A_g": 1e-9}}), h=4.0
    ) as fm:
        cur = fm.values()
        idx = free_of(fm, ["geodesic_bending"])
        free = free_of(fm, START)
        spread = candidate_start(fm, cur, free, idx, 0.0, np.inf)
        serial_calls = []
        orig = local.spread
        try:
            local.spread = lambda f, items, ev: serial_calls.append(1) or [ev(x) for x in items]
            alone = candidate_start(fm, cur, free, idx, 0.0, np.inf)
        finally:
            local.spread = orig
        assert serial_calls and np.array_equal(spread, alone) and same_on_all_ranks(spread)


@parallel
def test_other_ranks_say_nothing_while_a_rank_local_model_builds():
    """Every rank builds the rank-local model on its own communicator, so each is "rank 0" of
    it; only the world's rank 0 may log (``ranks.one_voice``). A handler on every rank
    collects what the package logs there, whatever the terminal's configuration."""
    exp = sy.template(48.0, 24.0, [1.0], sy.grid_points(48.0, 24.0, 4, 2), angles=(45.0, 135.0))
    records: list[logging.LogRecord] = []
    handler = logging.Handler(level=logging.DEBUG)
    handler.emit = records.append
    package = logging.getLogger("fabricsurf")
    level = package.level
    package.setLevel(logging.DEBUG)
    package.addHandler(handler)
    try:
        with ForwardModel(exp, full_model(["fibre_stretch", "shear"], START), h=4.0) as fm:
            assert fm.local
            fm.run()
    finally:
        package.removeHandler(handler)
        package.setLevel(level)
    said = COMM.allgather("\n".join(r.getMessage() for r in records))
    assert "are the fibre lines" in said[0], said[0]
    assert said[1:] == [""] * (COMM.size - 1)


class _Local:
    """A stand-in for a rank-local forward model (spread needs comm, local and values)."""

    comm, local = COMM, True

    def values(self):
        return np.zeros(1)

    def set_values(self, vals):
        pass


@parallel
def test_spread_shares_inner_trials_when_the_outer_items_are_fewer_than_the_ranks():
    fm, inner = _Local(), []

    def outer(x):
        return sum(local.spread(fm, list(range(6)), lambda k: inner.append(k) or k * x))

    assert local.spread(fm, [2.0], outer) == [30.0]  # one refit, as diagnose --confirm 1
    assert sorted(inner) == list(range(COMM.rank, 6, COMM.size))  # its trials shared
    inner.clear()
    assert local.spread(fm, [1.0, 2.0], outer) == [15.0, 30.0]  # two refits: one per rank
    assert inner == list(range(6))  # each rank's refit runs its trials alone


@parallel
def test_rank_0_builds_first_and_its_error_is_everyones(tmp_path):
    mark = COMM.bcast(str(tmp_path / "rank0-built") if COMM.rank == 0 else None)

    def build():  # rank 0 leaves a mark; the others must find it (rank 0 compiled first)
        if COMM.rank == 0:
            open(mark, "w").close()
            return "built"
        with open(mark):
            return "found"

    assert local.rank0_first(COMM, True, build) == ("built" if COMM.rank == 0 else "found")

    def fails_on_rank_0():
        if COMM.rank == 0:
            raise ValueError("no such form")
        return "never reached on rank 0's failure"

    with pytest.raises(ValueError, match="no such form"):
        local.rank0_first(COMM, True, fails_on_rank_0)
