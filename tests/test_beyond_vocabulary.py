"""Beyond the vocabulary (docs/diagnosis.md, "Beyond the vocabulary"): after a diagnosis that
leaves an excess, the search of the feature library (fabricsurf/inverse/diagnosis/beyond/)
names an energy no named effect has.

Data: continuum bias tests of the generator, 40 × 20 mm at ±45°, fibre_stretch k_l = k_m = 30
and shear k_s = 0.5 N/mm, 8 × 4 points and the force at 1, 2 and 3 mm, made at h = 1.5 mm and
diagnosed at h = 3 mm (the h/2 check passes: χ²_h ≈ 32 against a band of 59 on the null data),
noise 0.01 mm / 0.02 N. (a) A user's shear–tension coupling ½k_c γ²((λ−1)+(μ−1)), k_c = 5 N/mm,
hidden from fibre_stretch + shear: the diagnosis adds yarn_slip (a tie with shear_locking) and
still leaves an excess; the search names the γ²((λ−1)+(μ−1)) feature, with k_c inside its
interval. (b) Nothing hidden: the diagnosis finds nothing missing and no feature's
linearised reduction comes near the rule, so nothing is refitted; forced, the search finds
nothing (Bonferroni over the library). (b') A weaker coupling under more noise: adequate, but
the gate opens and the search names it. (c) Every feature is linear in its modulus, its pasted
source registers as a user's effect with the same density, and the forms the vocabulary has
are excluded. The numbers of (a) are the same on 1 and 2 ranks (small meshes solve rank-local).
"""

import json
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest
from mpi4py import MPI

from fabricsurf.inverse.diagnosis.beyond import NOTHING, family_alpha, search_beyond
from fabricsurf.inverse.diagnosis.beyond import features as ft
from fabricsurf.inverse.diagnosis.beyond.rule import GATE_SHARE, SHARE_NEEDED, judge
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.term import Term
from fabricsurf.model.terms import EFFECTS, make_term
from fabricsurf.model.user_effects import check_linear, density_evaluator, register_effect

K_C = 5.0


@dataclass
class HiddenShearTension(Term):
    """½k_c γ²((λ−1)+(μ−1)), the user's term of tests/test_user_effects.py (made the data)."""

    k_c: float = 1.0
    name: ClassVar[str] = "hidden_shear_tension"
    units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}

    def density(self, kin, p):
        return 0.5 * p["k_c"] * kin.gamma**2 * ((kin.lam - 1) + (kin.mu - 1))


def data(k_c: float, seed: int, noise: float = 0.01):
    """The module docstring's bias test, with the coupling k_c hidden (0: nothing hidden)."""
    exp = sy.template(40.0, 20.0, [1.0, 2.0, 3.0], sy.grid_points(40.0, 20.0, 8, 4))
    model = [make_term("fibre_stretch", k_l=30.0, k_m=30.0), make_term("shear", k_s=0.5)]
    register_effect(HiddenShearTension)
    try:
        sy.continuum_data(exp, model + [HiddenShearTension(k_c=k_c)] if k_c else model, h=1.5)
    finally:
        EFFECTS.unregister(HiddenShearTension.name)
    return sy.add_noise(exp, noise, 0.02, seed)


def diagnosed(exp):
    return diagnose(exp, ["fibre_stretch", "shear"], h=3.0, confirm=2, max_effects=1)


@pytest.fixture(scope="module")
def hidden_coupling():
    exp = data(K_C, seed=21)
    d = diagnosed(exp)
    return d, search_beyond(d, exp)


def test_hidden_shear_tension_is_named(hidden_coupling):
    d, rec = hidden_coupling
    print(d.outcome(), rec["outcome"], rec["found"][0]["modulus"] if rec["found"] else None)
    assert not d.adequate  # the named effects leave an excess (yarn_slip, added, takes a part)
    assert rec["searched"] and len(rec["found"]) == 1
    f = rec["found"][0]
    assert f["feature"] == "shear_tension_plus" and not f["indistinguishable_from"]
    assert rec["outcome"].startswith("an energy ∝ γ²((λ−1)+(μ−1)) removes ")
    assert rec["outcome"].endswith(" of the excess (115 %); no named effect has this form")
    json.dumps(rec)  # the record goes into diagnosis.json
    lo, hi = f["modulus"]["ci95"]
    assert lo <= K_C <= hi and f["modulus"]["unit"] == "N/mm"
    assert f["share_of_excess"] > 0.8 and f["refit_misfit"] < 1.1 < f["misfit_before"]
    assert f["wald_p"] < f["wald_p_needed"] == family_alpha(len(rec["library"]))
    assert abs(sum(q["share"] for q in f["where"]) - 1.0) < 1e-9
    assert "class ShearTensionPlus(Term):" in f["source"]
    assert rec["multiple_testing"]["method"] == "Bonferroni"
    assert {"shear_quartic", "fibre_imbalance_plus"} <= {q["feature"] for q in rec["excluded"]}
    assert not [n for n in EFFECTS if EFFECTS.origin(n) == ft.ORIGIN]  # unregistered after


def test_same_numbers_on_one_and_two_ranks(hidden_coupling):
    """Measured serially; the 2-rank session must give them to the solver's tolerance."""
    f = hidden_coupling[1]["found"][0]
    print(MPI.COMM_WORLD.size, f["modulus"], f["refit_misfit"], f["misfit_before"])
    assert f["modulus"]["value"] == pytest.approx(MODULUS, rel=1e-4)
    assert f["refit_misfit"] == pytest.approx(REFIT_MISFIT, rel=1e-5)
    assert f["misfit_before"] == pytest.approx(MISFIT_BEFORE, rel=1e-5)


MODULUS, REFIT_MISFIT, MISFIT_BEFORE = 4.87357, 0.899480, 1.465941  # one rank, measured


@pytest.mark.parametrize("share, found", [(0.005, False), (0.05, False), (0.30, True)])
def test_a_feature_must_remove_a_quarter_of_the_excess(share, found):
    """10⁵ residuals with an excess of 10⁴ (χ² = 1.1·10⁵ at p = 4): a refit removing 0.5 % or
    5 % of it passes the corrected Wald and F tests (the cases that raised it: the search
    named features that took up a two-hundredth and a twentieth of a lattice's discreteness
    error), but it does not say what the model misses; 30 % does."""
    n, p, m = 100_000, 4, 12
    chi2 = 1.1 * (n - p)
    excess = chi2 - (n - p)
    row = {"refit_chi2": chi2 - share * excess, "wald_p": 1e-12, "significant": True}
    verdict = judge(row, chi2, p, n, m)
    assert verdict["f_statistic"] > verdict["f_needed"] and row["wald_p"] < family_alpha(m)
    assert verdict["share_of_excess"] == pytest.approx(share)
    assert verdict["share_needed"] == SHARE_NEEDED == 0.25
    assert verdict["significant"] is found


def test_null_data_nothing_found():
    """Adequate: the gate (best linearised Δχ² against a quarter of the corrected rule's and
    the h/2 check's χ²) stays shut, so no refit; forced, the rule finds nothing either."""
    exp = data(0.0, seed=22)
    d = diagnosed(exp)
    assert d.adequate and d.verdict is None
    rec = search_beyond(d, exp)
    door = rec["gate"]
    print(rec["outcome"], door)
    assert not rec["searched"] and rec["found"] == [] and not door["open"]
    assert rec["outcome"].startswith("not searched: the final model is adequate, and no feature")
    reach = max(GATE_SHARE * door["needed_delta_chi2"], door["discretisation_chi2"])
    assert door["linearised_delta_chi2"] < reach
    rec = search_beyond(d, exp, force=True)
    print(rec["outcome"])
    assert rec["searched"] and rec["found"] == [] and rec["outcome"].startswith(NOTHING)
    assert rec["forced_past"] == "the final model is adequate"
    assert rec["gate"] == door  # the same fit and run: the same numbers
    # a round refits only features within a quarter of the need: the two best-scored split
    # at that floor, and an outcome without refits says why
    floor = GATE_SHARE * door["needed_delta_chi2"]
    top = sorted(rec["rounds"][0], key=lambda q: -q["score"])[:2]
    assert all((q.get("refit_chi2") is not None) == (q["score"] >= floor) for q in top)
    if all(q.get("refit_chi2") is None for q in top):
        assert "none refitted" in rec["outcome"]


def test_adequate_but_one_direction_left():
    """A weaker coupling (k_c = 3 N/mm) under twice the noise: the named diagnosis calls the
    model adequate (its χ² test spreads over all 291 residuals), yet the coupling's own
    direction holds Δχ² ≈ 28 against 16 needed by the corrected rule: the gate opens and the
    search names it (in a tie with γ³, which the data cannot tell apart). The linearised
    reduction is the refit's to a few per cent (one linear modulus; the others barely move)."""
    exp = data(3.0, seed=21, noise=0.02)
    d = diagnosed(exp)
    rec = search_beyond(d, exp)
    door, first = rec["gate"], rec["rounds"][0][0]
    print(d.outcome(), rec["outcome"], door)
    assert d.adequate and d.verdict is None
    assert rec["searched"] and rec["forced_past"] is None and door["open"]
    assert [f["feature"] for f in rec["found"]] == ["shear_tension_plus"]
    assert door["feature"] == first["effect"] == "shear_tension_plus"
    assert door["linearised_delta_chi2"] == pytest.approx(first["delta_chi2"], rel=0.05)
    assert first["delta_chi2"] > door["needed_delta_chi2"]
    lo, hi = rec["found"][0]["modulus"]["ci95"]
    assert lo <= 3.0 <= hi


def test_features_linear_and_their_source_registers():
    """Each feature passes the user-effect linearity check; its pasted source, executed in a
    fresh namespace, registers through register_effect and gives the same density."""
    for spec in ft.SPECS:
        cls = ft.feature_class(spec)
        check_linear(cls, "features")
        namespace = {"__name__": f"pasted_{spec.name}"}
        exec(compile(spec.source, "pasted.py", "exec", dont_inherit=True), namespace)
        pasted = namespace[spec.class_name]
        assert pasted is not cls and pasted.name == spec.name
        register_effect(pasted, "pasted.py")
        try:
            ours, theirs = (density_evaluator(c(k=1.7))({"k": 1.7}) for c in (cls, pasted))
            np.testing.assert_allclose(theirs, ours, rtol=1e-13, atol=0.0)
            assert np.abs(ours).max() > 0
        finally:
            EFFECTS.unregister(spec.name)


def test_vocabulary_forms_excluded():
    """γ⁴ is shear_locking's, (λ−1)² − (μ−1)² fibre_stretch's; a registered user effect of the
    shear–tension form excludes that feature too; curvature features need 3D data."""
    kept, excluded = ft.library(three_d=False)
    why = {q["feature"]: q for q in excluded}
    assert why["shear_quartic"]["duplicates"] == ["shear_locking"]
    assert why["fibre_imbalance_minus"]["duplicates"] == ["fibre_stretch"]
    assert "planar" in why["curvature_coupling_plus"]["reason"]
    assert 10 <= len(kept) <= 16 and "shear_tension_plus" in [s.name for s in kept]
    assert "shear_bending" in [s.name for s in ft.library(three_d=True)[0]]
    register_effect(HiddenShearTension)
    try:
        kept, excluded = ft.library()
        dup = {q["feature"]: q.get("duplicates") for q in excluded}
        assert dup["shear_tension_plus"] == dup["shear_tension_minus"] == ["hidden_shear_tension"]
    finally:
        EFFECTS.unregister(HiddenShearTension.name)
