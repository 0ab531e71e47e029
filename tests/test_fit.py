"""Least-squares fit with tangent sensitivities: recovers the moduli of noisy data made with the
same discretisation within three standard deviations each (for four moduli a fresh noise draw
breaks this with probability about 1 %; the draw here is fixed), at a misfit of the noise level
(1 within about three of its standard deviations, 1/√(2n) for n residuals); the fit CLI saves a
reusable model."""

import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.cli import main
from fabricsurf.inverse.contract.data import write_experiment
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy

TRUTH = {
    "fibre_stretch": {"k_l": 25.0, "k_m": 25.0},
    "shear": {"k_s": 0.4},
    "geodesic_bending": {"A_g": 12.0},
}


def noisy(seed):
    exp = sy.template(48.0, 24.0, [1.0, 2.0], sy.grid_points(48.0, 24.0, 8, 4))
    sy.continuum_data(exp, full_model(list(TRUTH), TRUTH), h=4.0)
    return sy.add_noise(exp, 0.005, 0.005, seed)


def test_fit_recovers_moduli():
    exp = noisy(31)
    start = {
        "fibre_stretch": {"k_l": 10.0, "k_m": 10.0},
        "shear": {"k_s": 1.0},
        "geodesic_bending": {"A_g": 3.0},
    }
    fm = ForwardModel(exp, full_model(list(TRUTH), start), h=4.0)
    idx = [i for i, (t, _) in enumerate(fm.params) if t.name in TRUTH]
    res = fit(fm, idx)
    truth = np.array([TRUTH[t.name][p] for t, p in fm.params if t.name in TRUTH])
    z = (res.values[idx] - truth) / res.std[idx]
    print("fitted", res.values[idx], "+-", res.std[idx], "z", z, "runs", res.forward_runs)
    assert np.all(np.abs(z) < 3.0)
    assert 0.8 < res.misfit["combined"] < 1.2


def test_fit_cli_saves_model_for_compare(tmp_path):
    comm = MPI.COMM_WORLD
    exp = noisy(32)
    root = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    if comm.rank == 0:
        write_experiment(root / "data", exp)
    comm.barrier()
    args = [str(root / "data"), "--terms", "fibre_stretch,shear,geodesic_bending", "--h", "4"]
    assert main(["fit", *args, "--out", str(root / "fit")]) == 0
    comm.barrier()
    saved = json.loads((root / "fit" / "fit.json").read_text())
    assert set(saved["std"]) == {
        "fibre_stretch.k_l",
        "fibre_stretch.k_m",
        "shear.k_s",
        "geodesic_bending.A_g",
    }
    assert (
        main(
            [
                "compare",
                str(root / "data"),
                "--params",
                str(root / "fit" / "fit.json"),
                "--h",
                "4",
                "--out",
                str(root / "cmp"),
            ]
        )
        == 0
    )
    comm.barrier()
    m = json.loads((root / "cmp" / "misfit.json").read_text())
    assert np.isclose(m["chi2"], saved["chi2"], rtol=1e-6)


def test_fit_cli_holds_fixed_terms(tmp_path, capsys):
    """``fit --fixed``: the yarns held at their --params moduli (as a tensile test gives them),
    the other moduli fitted within three standard deviations of the truth; fit.json marks the
    held ones ``fixed``, with no interval and a standard deviation of 0 (as the diagnosis
    does). A --fixed term not in --terms, or one whose moduli --params does not give, is
    refused before any solve, naming the option."""
    comm = MPI.COMM_WORLD
    exp = noisy(33)
    root = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    start = {
        "fibre_stretch": TRUTH["fibre_stretch"],
        "shear": {"k_s": 1.0},
        "geodesic_bending": {"A_g": 3.0},
    }
    if comm.rank == 0:
        write_experiment(root / "data", exp)
        (root / "p.json").write_text(json.dumps(start))
        (root / "s.json").write_text(json.dumps({"shear": {"k_s": 1.0}}))
    comm.barrier()
    terms = ["--terms", "fibre_stretch,shear,geodesic_bending", "--h", "4"]
    args = [str(root / "data"), *terms, "--params", str(root / "p.json")]
    assert main(["fit", *args, "--fixed", "fibre_stretch", "--out", str(root / "fit")]) == 0
    comm.barrier()
    saved = json.loads((root / "fit" / "fit.json").read_text())
    for p in ("k_l", "k_m"):
        held = saved["moduli"][f"fibre_stretch.{p}"]
        assert held == {"value": 25.0, "fixed": True} and saved["std"][f"fibre_stretch.{p}"] == 0
    for name, truth in (("shear.k_s", 0.4), ("geodesic_bending.A_g", 12.0)):
        assert abs(saved["moduli"][name]["value"] - truth) < 3.0 * saved["std"][name], name
    capsys.readouterr()
    assert main(["fit", *args, "--fixed", "twist", "--out", str(root / "bad")]) == 2
    out = capsys.readouterr().out
    assert comm.rank > 0 or "--fixed twist: 'twist' is not a baseline term (--terms" in out
    bad = [str(root / "data"), *terms, "--params", str(root / "s.json")]
    assert main(["fit", *bad, "--fixed", "fibre_stretch", "--out", str(root / "bad")]) == 2
    out = capsys.readouterr().out
    assert comm.rank > 0 or "--fixed fibre_stretch: a fixed term is held at its moduli" in out
