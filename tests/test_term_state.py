"""The state of a term (fabricsurf/model/term.py): no change at a distance, pickling, copying.

``Term.set`` changes the constants of the forms built from that very term object. The owners
of forms (a BiasExtension, an experiment plug-in, a forward model) build them from their own
copies, so a term a user changes after building a test changes the tests built afterwards
only; the owner's own terms (``test.model``, a forward model's ``set_values``) still change its
constants without recompiling. A term pickles and copies as its fields, without live forms;
the bi-pantographic term's own penalty stretch follows what was written into its form.
"""

import copy
import pickle

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.inverse.forward.runs import ForwardModel, ForwardSet
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.materials import PantographBending, bipantographic
from fabricsurf.model.terms import EFFECTS, FibreStretch, GeodesicBending, Shear
from fabricsurf.model.user_effects import effects_from

COMM = MPI.COMM_WORLD
LENGTH, WIDTH, H = 187.0, 119.0, 17.0
"""mm: the README's specimen on a coarse mesh."""
UBAR, STEPS = 0.05 * LENGTH, 2


def readme_model():
    """The model of the README's first example."""
    return [FibreStretch(k_l=30.0, k_m=30.0), Shear(k_s=0.5), GeodesicBending(A_g=40.0)]


def k_s_in(test: BiasExtension) -> float:
    """k_s in the constants of the test's own energy form."""
    return float(test.problem.energy.constants_of(test.model[1])["k_s"].value)


def rerun(test: BiasExtension):
    """The test run again from the reference state."""
    test.problem.u.x.array[:] = 0.0
    return test.run(UBAR, STEPS)


def test_readme_second_experiment_leaves_the_first_alone():
    """The README's first example: a test run, ``set`` on the shared term list, a second test.
    The first test keeps k_s = 0.5 (its constants, its terms, and what it computes when run
    again); the second has k_s = 0.8 and a larger force. Setting the first test's own term
    changes it, through the same compiled forms, to the second's answer. (Before, ``set`` on
    the list rewrote the first test's constants to 0.8.)"""
    model = readme_model()
    first = BiasExtension(model, LENGTH, WIDTH, h=H)
    result = first.run(UBAR, STEPS)
    assert k_s_in(first) == 0.5
    model[1].set(k_s=0.8)
    second = BiasExtension(model, LENGTH, WIDTH, h=H)
    stiffer = second.run(UBAR, STEPS)
    assert k_s_in(first) == 0.5 and first.model[1].k_s == 0.5
    assert k_s_in(second) == 0.8 and second.model[1].k_s == 0.8
    assert all(a is not b for a, b in zip(first.model, model))
    assert stiffer.force[-1] > result.force[-1] * (1 + 1e-3)
    assert rerun(first).force == pytest.approx(result.force, rel=1e-6)
    first.model[1].set(k_s=0.8)  # the owner's own term: its constants follow
    assert k_s_in(first) == 0.8 and k_s_in(second) == 0.8 and model[1].k_s == 0.8
    assert rerun(first).force == pytest.approx(stiffer.force, rel=1e-6)
    first.model[1].set(k_s=0.3)
    assert k_s_in(second) == 0.8 and model[1].k_s == 0.8


def small_experiment():
    return sy.template(40.0, 20.0, [0.8, 1.6], sy.grid_points(40.0, 20.0, 4, 2))


def moduli_in(fm: ForwardModel) -> list[float]:
    """The moduli in the constants of the forward model's plug-in's energy form."""
    energy = fm.test.problem.energy
    return [float(energy.constants_of(t)[p].value) for t, p in fm.params]


def test_forward_models_set_their_own_terms():
    """A ForwardSet's experiments work on copies of the terms given: ``set`` on those leaves
    them alone; ``set_values`` (what a fit does) reaches the constants of every experiment and
    of the scouts, and leaves the terms given alone."""
    model = readme_model()[:2]
    exps = [small_experiment(), small_experiment()]
    with ForwardSet(exps, model, h=10.0) as fs:
        scout = fs.coarse()
        model[1].set(k_s=0.9)
        start = [30.0, 30.0, 0.5]
        for m in [*fs.models, *scout.models]:
            assert moduli_in(m) == start and list(m.values()) == start
        vals = np.array([20.0, 25.0, 0.3])
        fs.set_values(vals)
        for m in [*fs.models, *scout.models]:
            assert moduli_in(m) == list(vals) and list(m.values()) == list(vals)
        assert [t.values() for t in model] == [{"k_l": 30.0, "k_m": 30.0}, {"k_s": 0.9}]
        assert fs.model is fs.models[0].model and fs.model[1].k_s == 0.3
        with ForwardModel(exps[0], fs.model, h=10.0) as fm:  # built at the current moduli
            assert moduli_in(fm) == list(vals)
            fm.set_values(2 * vals)
            assert moduli_in(fs.models[0]) == list(vals)


def nondefault(cls):
    """A term of ``cls`` with every modulus moved off its default (signed ones negative)."""
    t = cls()
    values = {}
    for p in t.parameters():
        v = float(getattr(t, p))
        values[p] = -(abs(v) + 0.25) if p in cls.signed else 1.5 * v + 0.25
    if isinstance(t, PantographBending):
        values["penalty_stretch"] = 1.02
        values["gamma"] = t.gamma
    t.set(**values)
    return t


def check_state(term, msh) -> None:
    """Pickle, copy.copy, copy.deepcopy and Term.copy of ``term`` (which has a live form) give
    an equal term of the same class with no live forms; ``set`` on either leaves the other,
    and the other's form, alone."""
    consts = term.constants(msh)
    p = term.parameters()[0]
    before = float(getattr(term, p))
    for other in (
        pickle.loads(pickle.dumps(term)),
        copy.copy(term),
        copy.deepcopy(term),
        term.copy(),
    ):
        assert type(other) is type(term) and other == term and other is not term
        assert other.values() == term.values() and len(other._live) == 0
        assert len(term._live) == 1
        changed = before + 0.5 if before >= 0 else before - 0.5
        other.set(**{p: changed})
        assert getattr(term, p) == before and other != term
        assert np.allclose(_value(consts[p]), before)
        mine = other.constants(msh)
        term.set(**{p: before})  # reaches term's form only
        assert np.allclose(_value(mine[p]), changed)
        assert len(term._live) == 1


def _value(c):
    return c.x.array if hasattr(c, "x") else c.value


@pytest.mark.parametrize("name", list(EFFECTS))
def test_every_effect_pickles_and_copies(name):
    msh = dmesh.create_unit_square(COMM, 2, 2)
    check_state(nondefault(EFFECTS[name]), msh)


def test_materials_pickle_and_copy():
    msh = dmesh.create_unit_square(COMM, 2, 2)
    for t in [*bipantographic(), nondefault(PantographBending)]:
        check_state(t, msh)


EFFECT = '''"""A user's effect."""
from dataclasses import dataclass
from typing import ClassVar

from fabricsurf import Term


@dataclass
class ShearTensionState(Term):
    """½k_c γ² ((λ−1) + (μ−1))."""

    k_c: float = 1.0
    name: ClassVar[str] = "shear_tension_state"
    units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}

    def density(self, kin, p):
        return 0.5 * p["k_c"] * kin.gamma**2 * ((kin.lam - 1) + (kin.mu - 1))
'''


def test_a_user_effect_pickles_and_copies(tmp_path):
    """An effect registered from the user's file (``--effects``, load_effects) pickles and
    copies like a built-in (by its class, importable while it is registered)."""
    path = tmp_path / "effect.py"
    if COMM.rank == 0:
        path.write_text(EFFECT, encoding="utf-8")
    path = COMM.bcast(path if COMM.rank == 0 else None)
    COMM.barrier()
    with effects_from([path]) as names:
        assert names == ["shear_tension_state"]
        term = nondefault(EFFECTS["shear_tension_state"])
        assert term.k_c == 1.75
        check_state(term, dmesh.create_unit_square(COMM, 2, 2))


def test_cellwise_penalty_stretch_keeps_the_terms_value():
    """``set_penalty_stretch`` writes one form cell by cell and sets the term's own value to
    the largest written over all ranks (uniform: that value), so a copy, a pickle or a new form
    of the term is penalised at least as strongly; ``set`` makes every form uniform again."""
    msh = dmesh.create_unit_square(COMM, 4, 4)
    t = PantographBending()
    consts = t.constants(msh)
    n = len(consts["penalty_stretch"].x.array)  # DG0: one per local cell, ghosts included
    t.set_penalty_stretch(consts, np.full(n, 1.04))
    assert t.penalty_stretch == 1.04
    assert pickle.loads(pickle.dumps(t)).penalty_stretch == 1.04
    assert np.all(t.copy().constants(msh)["penalty_stretch"].x.array == 1.04)
    rho = 1.0 + 0.01 * np.arange(n) / max(n, 1) + 0.05 * COMM.rank
    t.set_penalty_stretch(consts, rho)
    largest = COMM.allreduce(float(rho.max()), op=MPI.MAX)
    assert t.penalty_stretch == largest >= 1.0 + 0.05 * (COMM.size - 1)
    t.set(penalty_stretch=1.0)
    assert np.all(consts["penalty_stretch"].x.array == 1.0) and t.penalty_stretch == 1.0
    with pytest.raises(ValueError, match="cos γ < 1"):
        t.set_penalty_stretch(consts, np.full(n, 1.2))
    assert t.penalty_stretch == 1.0
