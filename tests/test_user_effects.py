"""A user's own effect, without editing the package (docs/usage.md, "Adding your own effect"):
a shear–tension coupling ½k_c γ² ((λ−1) + (μ−1)) in a file of its own goes through
``--effects`` into ``terms``, ``compare`` and ``fit`` and through the Python API; a file that
cannot serve (name clash, import error, density not linear in its moduli, no Term, no unit) is
refused before any solve with exit 2 on every rank, naming the file.

The data are noise-free and made with the same discretisation as the fit, so a fit recovers the
coupling modulus that made them to the fit's own tolerance, and compare at those moduli has a
misfit of round-off: a number that the package could not produce without the user's term in
the model (without it the misfit is ~1.4, the noise level is 1).
"""

import json
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from test_hardening import good_experiment, rejected_message, run_cli

from fabricsurf.inverse.contract.data import write_experiment
from fabricsurf.inverse.diagnosis.diagnose import check_unsigned, full_model, visible_effects
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.params import load_params
from fabricsurf.inverse.fitting.preconditions import positive_start
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.registry import BUILTIN
from fabricsurf.model.terms import EFFECTS, make_term, parse_terms
from fabricsurf.model.user_effects import effects_from

COMM = MPI.COMM_WORLD
TRUTH = {
    "fibre_stretch": {"k_l": 25.0, "k_m": 25.0},
    "shear": {"k_s": 0.4},
    "shear_tension": {"k_c": 2.0},
}
TERMS = "fibre_stretch,shear,shear_tension"

EFFECT = '''"""My effects."""
from dataclasses import dataclass
from typing import ClassVar

from fabricsurf import Term


@dataclass
class ShearTension(Term):
    """½k_c γ² ((λ−1) + (μ−1)): shear stiffening under fibre tension."""

    k_c: float = 1.0
    name: ClassVar[str] = "{name}"
    units: ClassVar[dict[str, str]] = {units}
    signed: ClassVar[tuple[str, ...]] = {signed}

    def density(self, kin, p):
        return 0.5 * {modulus} * kin.gamma**2 * ((kin.lam - 1) + (kin.mu - 1))
'''


def effect_source(
    name="shear_tension", units='{"k_c": "N/mm"}', signed="()", modulus='p["k_c"]'
) -> str:
    return EFFECT.format(name=name, units=units, signed=signed, modulus=modulus)


def source_file(name: str, text: str):
    def make(base: Path) -> None:
        (base / name).write_text(text, encoding="utf-8")

    return make


def both(*makers):
    def make(base: Path) -> None:
        for m in makers:
            m(base)

    return make


def params_json(name: str, content: dict):
    return source_file(name, json.dumps(content))


CASES = [
    dict(
        id="effects-name-clash",
        klass="`--effects` file whose effect takes a built-in's name",
        make=source_file("clash.py", effect_source(name="shear")),
        argv=["compare", "good", "--terms", "shear", "--effects", "clash.py", "--out", "out"],
        pattern=r"clash.py: effect name 'shear' \(ShearTension\) is already taken by a "
        "built-in effect",
    ),
    dict(
        id="effects-clash-between-files",
        klass="two `--effects` files defining one name",
        make=both(
            source_file("mine.py", effect_source()), source_file("mine_too.py", effect_source())
        ),
        argv=[
            "compare",
            "good",
            "--terms",
            "shear",
            "--effects",
            "mine.py,mine_too.py",
            "--out",
            "out",
        ],
        pattern=r"mine_too.py: effect name 'shear_tension' \(ShearTension\) is already taken "
        "by the effect from mine.py",
    ),
    dict(
        id="effects-import-error",
        klass="`--effects` file that fails to import",
        make=source_file("broken_effect.py", "import math\nx = 1 / 0\n"),
        argv=[
            "compare",
            "good",
            "--terms",
            "shear",
            "--effects",
            "broken_effect.py",
            "--out",
            "out",
        ],
        pattern=r"--effects broken_effect.py: cannot be imported \(ZeroDivisionError: "
        "division by zero\\)",
    ),
    dict(
        id="effects-nonlinear",
        klass="`--effects` effect whose density is not linear in its moduli",
        make=source_file("squared.py", effect_source(modulus='p["k_c"]**2')),
        argv=[
            "fit",
            "good",
            "--terms",
            "shear,shear_tension",
            "--effects",
            "squared.py",
            "--out",
            "out",
        ],
        pattern=r"squared.py: effect 'shear_tension' \(ShearTension\): its density is not "
        r"linear in its moduli \(k_c\): W\(2p\) = 2 W\(p\) fails",
    ),
    dict(
        id="effects-no-term",
        klass="`--effects` file that defines no effect",
        make=source_file("no_term.py", "K = 1.0\n"),
        argv=["compare", "good", "--terms", "shear", "--effects", "no_term.py", "--out", "out"],
        pattern=r"--effects no_term.py: defines no subclass of fabricsurf's Term with a name",
    ),
    dict(
        id="effects-no-unit",
        klass="`--effects` effect with a modulus without a unit",
        make=source_file("no_unit.py", effect_source(units="{}")),
        argv=["compare", "good", "--terms", "shear", "--effects", "no_unit.py", "--out", "out"],
        pattern=r"no_unit.py: effect 'shear_tension' \(ShearTension\): no unit declared "
        "for k_c",
    ),
    dict(
        id="effects-missing-file",
        klass="`--effects` naming a file that does not exist",
        make=lambda base: None,
        argv=["terms", "--effects", "absent.py"],
        pattern=r"--effects absent.py: no such file",
    ),
    dict(
        id="diagnose-signed-modulus",
        klass="`diagnose` of an effect whose modulus may be negative",
        make=both(
            source_file("signed.py", effect_source(signed='("k_c",)')),
            params_json("signed.json", {"shear": {"k_s": 0.4}, "shear_tension": {"k_c": -1.0}}),
        ),
        argv=[
            "diagnose",
            "good",
            "--terms",
            "shear,shear_tension",
            "--effects",
            "signed.py",
            "--params",
            "signed.json",
            "--out",
            "out",
        ],
        pattern=r"--terms shear,shear_tension: shear_tension.k_c may be negative \(signed\), "
        "and diagnose works with moduli ≥ 0",
    ),
]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """rank 0's directory, shared: ``good`` (the hardening tests' data), ``st`` (noise-free
    data made with the coupling, TRUTH), the user's files and the CASES' files."""
    base = Path(COMM.bcast(str(tmp_path_factory.mktemp("user")) if COMM.rank == 0 else None))
    if COMM.rank == 0:
        write_experiment(base / "good", good_experiment())
        (base / "effect.py").write_text(effect_source(), encoding="utf-8")
        (base / "signed.py").write_text(effect_source(signed='("k_c",)'), encoding="utf-8")
        for c in CASES:
            c["make"](base)
    COMM.barrier()
    with effects_from([base / "effect.py"]):
        exp = truth_data()
    if COMM.rank == 0:
        write_experiment(base / "st", exp)
    COMM.barrier()
    return base


def truth_data():
    """40 × 20 mm bias specimen at 1 and 2 mm, 4 × 2 DIC points, made with TRUTH at h = 10."""
    exp = sy.template(40.0, 20.0, [1.0, 2.0], sy.grid_points(40.0, 20.0, 4, 2))
    sy.continuum_data(exp, parse_terms(TERMS, TRUTH), h=10.0)
    exp.noise_std, exp.force_noise_std = 0.01, 0.01
    return exp


@pytest.fixture
def in_root(root, monkeypatch):
    monkeypatch.chdir(root)
    return root


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_refused_before_any_solve(case, in_root, capsys, monkeypatch):
    """Each refusal: exit 2 on every rank, one message naming the file, nothing built, and
    no effect left registered."""
    msg = rejected_message(case, in_root, capsys, monkeypatch)
    assert len(msg.splitlines()) == 1, msg
    assert EFFECTS.user_effects() == []


def test_terms_lists_user_effect_with_origin(in_root, capsys):
    rc, out = run_cli(["terms", "--effects", "signed.py"], capsys)
    assert rc == 0, out
    line = next(ln for ln in out.splitlines() if ln.startswith("shear_tension "))
    assert "k_c (N/mm, signed)" in line
    assert "½k_c γ² ((λ−1) + (μ−1)): shear stiffening under fibre tension." in out
    assert "(your effect, from signed.py)" in out
    assert "shear_tension" not in EFFECTS  # registered for the command only


def test_compare_and_fit_on_the_command_line(in_root, capsys):
    """compare at the moduli that made the data: round-off misfit with the user's term, and
    a signed (negative) modulus accepted; fit recovers k_c = 2 from a start at 1."""
    (in_root / f"truth{COMM.rank}.json").write_text(json.dumps(TRUTH))
    wrong = TRUTH | {"shear_tension": {"k_c": -1.0}}
    (in_root / f"negative{COMM.rank}.json").write_text(json.dumps(wrong))
    common = ["--effects", "signed.py", "--h", "10"]
    rc, out = run_cli(
        ["compare", "st", "--params", f"truth{COMM.rank}.json", *common, "--out", "cmp_truth"],
        capsys,
    )
    assert rc == 0, out
    rc, out = run_cli(
        [
            "compare",
            "st",
            "--params",
            f"negative{COMM.rank}.json",
            *common,
            "--out",
            "cmp_negative",
        ],
        capsys,
    )
    assert rc == 0, out
    COMM.barrier()
    at_truth = json.loads((in_root / "cmp_truth" / "misfit.json").read_text())
    negative = json.loads((in_root / "cmp_negative" / "misfit.json").read_text())
    assert at_truth["combined"] < 1e-6, at_truth["combined"]  # the data's own model
    assert negative["combined"] > 0.1, negative["combined"]  # k_c = -1 is seen
    assert negative["stability"]["states"] > 0  # a signed model's energy is checked
    rc, out = run_cli(
        ["fit", "st", "--terms", TERMS, "--effects", "effect.py", "--h", "10", "--out", "fit"],
        capsys,
    )
    assert rc == 0, out
    COMM.barrier()
    saved = json.loads((in_root / "fit" / "fit.json").read_text())
    assert saved["params"]["shear_tension"]["k_c"] == pytest.approx(2.0, rel=1e-3)
    assert saved["provenance"]["terms"] == TERMS.split(",")
    assert EFFECTS.user_effects() == []


@pytest.fixture
def registered(root):
    """The user's module registered through the Python API for one test."""
    with effects_from([root / "effect.py"]) as names:
        yield names


def test_python_api(registered, root):
    """register → make_term, --params files and the fit find the effect; the origin is the
    file; the fit recovers the modulus from noise-free data."""
    assert registered == ["shear_tension"]
    assert EFFECTS.origin("shear_tension") == str(root / "effect.py")
    assert EFFECTS.origin("shear") == BUILTIN
    term = make_term("shear_tension", k_c=3.0)
    assert term.values() == {"k_c": 3.0}
    from fabricsurf.inverse.contract.data import load_experiment

    exp = load_experiment(root / "st")
    start = parse_terms(
        TERMS,
        {
            "fibre_stretch": {"k_l": 20.0, "k_m": 20.0},
            "shear": {"k_s": 0.5},
            "shear_tension": {"k_c": 1.0},
        },
    )
    res = fit(ForwardModel(exp, start, h=10.0))
    np.testing.assert_allclose(res.values, [25.0, 25.0, 0.4, 2.0], rtol=1e-3)
    # a diagnosis candidate by default, like a built-in the data can see (at modulus 0)
    assert "shear_tension" in visible_effects([exp])
    pool = {t.name: t.values() for t in full_model(["fibre_stretch", "shear"])}
    assert pool["shear_tension"] == {"k_c": 0.0}


def test_register_effect_decorator_and_signed_moduli(tmp_path):
    """``register_effect`` as a decorator; a signed modulus accepted by the term and a
    --params file, refused by the library's fit with the reason; a second registration of
    the name refused."""
    from dataclasses import dataclass
    from typing import ClassVar

    from fabricsurf import Term, register_effect

    @register_effect
    @dataclass
    class Coupling(Term):
        """½k_c γ² (λ − 1)."""

        k_c: float = 1.0
        name: ClassVar[str] = "coupling_test"
        units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}
        signed: ClassVar[tuple[str, ...]] = ("k_c",)

        def density(self, kin, p):
            return 0.5 * p["k_c"] * kin.gamma**2 * (kin.lam - 1)

    try:
        assert EFFECTS.origin("coupling_test") == __file__
        assert make_term("coupling_test", k_c=-2.0).k_c == -2.0
        f = tmp_path / "p.json"
        f.write_text(json.dumps({"coupling_test": {"k_c": -2.0}}))
        assert load_params(f) == {"coupling_test": {"k_c": -2.0}}
        with pytest.raises(ValueError, match="must be finite and >= 0"):
            make_term("shear", k_s=-1.0)  # built-in moduli stay non-negative
        with pytest.raises(ValueError, match="already taken by the effect from"):
            register_effect(Coupling)
        assert "coupling_test" not in [t.name for t in full_model(["shear"])]
        with pytest.raises(ValueError, match="signed effects can be compared but not diagnosed"):
            check_unsigned(["shear", "coupling_test"])
        with pytest.raises(ValueError, match=r"coupling_test\.k_c may be negative"):
            positive_start([make_term("coupling_test", k_c=-2.0)], command="diagnose")
        positive_start([make_term("coupling_test", k_c=-2.0)], command="fit")  # fit takes it
    finally:
        EFFECTS.unregister("coupling_test")
    assert "coupling_test" not in EFFECTS


def test_every_builtin_passes_the_checks():
    """The check refuses no linear density: every built-in (quadratic, quartic, ln cosh with
    conditionals, second-gradient, out-of-plane) passes it, as it would from a user's file."""
    from fabricsurf.model.user_effects import _check_declarations, check_linear

    for name, cls in EFFECTS.items():
        _check_declarations(cls, BUILTIN)
        check_linear(cls, BUILTIN)
