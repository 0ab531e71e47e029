"""Experiment plug-ins through one pipeline: compare, fit and diagnose work for every plug-in.

* picture frame: the homogeneous pure shear is exact for every energy of the vocabulary, so the
  crosshead force and its sensitivities equal the closed form a² W′(γ)/(a sin φ) to solver
  tolerance (clamped fibres, the case with the Nitsche gradient clamp; the pinned frame enters
  the joint fit below, and one exact case per kernel keeps the suite's time);
* the real force-only Cao et al. 2008 curve loads and goes through compare, fit and diagnose;
* a bias test (field + force) and a picture frame (force only) made from one material are fitted
  together: one set of moduli, misfit per experiment, the truth recovered; compared and
  diagnosed together through the CLI (no effect is missing, so no verdict).
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fabricsurf.cli import main
from fabricsurf.datasets import cao2008_plain_weave
from fabricsurf.experiments.picture_frame import frame_force_exact, frame_shear_angle
from fabricsurf.inverse.contract.data import load_experiment, write_experiment
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardModel, ForwardSet
from fabricsurf.inverse.synthetic import generate as sy

CAO = cao2008_plain_weave()
MATERIAL = {
    "fibre_stretch": {"k_l": 40.0, "k_m": 40.0},
    "shear": {"k_s": 0.4},
    "shear_locking": {"k4": 0.8, "k6": 0.5},
    "geodesic_bending": {"A_g": 5.0},
}


def frame(frame_kind: str, path=(6.0, 12.0, 20.0)):
    return sy.template(
        80.0,
        80.0,
        list(path),
        np.zeros((0, 2)),
        angles=(0.0, 90.0),
        test="picture_frame",
        options={"frame": frame_kind},
    )


def dW(g):
    s, lk = MATERIAL["shear"], MATERIAL["shear_locking"]
    return s["k_s"] * g + lk["k4"] * g**3 + lk["k6"] * g**5


def test_picture_frame_force_is_exact():
    exp = frame("clamped")
    fm = ForwardModel(exp, full_model(list(MATERIAL), MATERIAL), h=20.0)
    p = fm.run(sens=True)
    exact = np.array([frame_force_exact(d, 80.0, dW) for d in exp.path])
    assert np.allclose(p.force, exact, rtol=1e-8), (p.force, exact)
    g = np.array([frame_shear_angle(d, 80.0) for d in exp.path])
    assert math.degrees(g[-1]) > 20.0
    k4 = fm.names.index("shear_locking.k4")
    dgdd = exact / np.array([dW(x) for x in g])
    assert np.allclose(p.dforce[:, k4], dgdd * g**3, rtol=1e-6)


def test_cao_force_only_compare_and_fit(tmp_path):
    """The real curve loads as it is; compare and fit run on every fourth step of it (a copy
    written by the library, to keep the test short; the woven-fabric demo uses all 43); the
    saved fit.json is accepted by compare --params (same χ²) and bias --params."""
    exp = load_experiment(CAO)
    assert not exp.has_field and exp.has_force and len(exp.steps) == 43
    assert exp.source["reference"].startswith("Cao J.")
    comm = MPI.COMM_WORLD
    root = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    keep = np.arange(0, 43, 4)
    exp.steps, exp.path, exp.force = np.arange(1, len(keep) + 1), exp.path[keep], exp.force[keep]
    if comm.rank == 0:
        write_experiment(root / "cao", exp)
    comm.barrier()
    args = [str(root / "cao"), "--terms", "fibre_stretch,shear", "--h", "28.75"]
    assert main(["compare", *args, "--out", str(root / "cmp")]) == 0
    assert main(["fit", *args, "--out", str(root / "fit")]) == 0
    comm.barrier()
    m = json.loads((root / "cmp" / "misfit.json").read_text())["experiments"][0]
    assert m["field_rms"] is None and m["force_rms"] > 0 and m["n"] == len(keep)
    f = json.loads((root / "fit" / "fit.json").read_text())
    assert f["misfit"]["combined"] < m["combined"]
    assert f["provenance"]["inputs"] == [str(root / "cao")]
    assert (
        main(
            [
                "compare",
                str(root / "cao"),
                "--params",
                str(root / "fit" / "fit.json"),
                "--h",
                "28.75",
                "--out",
                str(root / "again"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "bias",
                "--terms",
                "fibre_stretch,shear",
                "--params",
                str(root / "fit" / "fit.json"),
                "--length",
                "230",
                "--width",
                "115",
                "--h",
                "28.75",
                "--ubar",
                "10",
                "--steps",
                "1",
                "--out",
                str(root / "bias"),
            ]
        )
        == 0
    )
    comm.barrier()
    again = json.loads((root / "again" / "misfit.json").read_text())
    assert abs(again["chi2"] - f["chi2"]) <= 1e-8 * f["chi2"]
    assert (root / "cmp" / "force.png").is_file() and not (root / "cmp" / "per_point.csv").exists()


def test_bias_and_frame_fitted_together(tmp_path):
    truth = {k: MATERIAL[k] for k in ("fibre_stretch", "shear")}
    bias = sy.template(40.0, 20.0, [0.8, 1.6], sy.grid_points(40.0, 20.0, 6, 3), name="bias")
    sy.continuum_data(bias, full_model(list(truth), truth), h=4.0)
    pf = frame("pinned", path=(4.0, 8.0))
    pf.name = "frame"
    sy.continuum_data(pf, full_model(list(truth), truth), h=20.0)
    sy.add_noise(bias, 0.005, 0.005, 5)
    sy.add_noise(pf, 0.0, 0.005, 6)
    start = {"fibre_stretch": {"k_l": 10.0, "k_m": 10.0}, "shear": {"k_s": 1.0}}
    model = full_model(list(truth), start)
    fs = ForwardSet([bias, pf], model, h=None)
    assert [m.h for m in fs.models] == [2.0, 10.0]  # each test's default mesh
    fs.models[0] = ForwardModel(bias, model, h=4.0)  # the data's own mesh: no form error
    idx = [i for i, (t, _) in enumerate(fs.params) if t.name in truth]
    res = fit(fs, idx)
    vals = dict(zip(res.names, res.values))
    assert vals["shear.k_s"] == pytest.approx(0.4, rel=0.02)
    assert [e["experiment"] for e in res.misfit["experiments"]] == ["bias", "frame"]
    assert 0.7 < res.misfit["combined"] < 1.3
    comm = MPI.COMM_WORLD
    root = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    if comm.rank == 0:
        write_experiment(root / "bias", bias)
        write_experiment(root / "frame", pf)
    comm.barrier()
    assert (
        main(
            [
                "compare",
                str(root / "bias"),
                str(root / "frame"),
                "--terms",
                "fibre_stretch,shear",
                "--h",
                "4",
                "--out",
                str(root / "cmp"),
            ]
        )
        == 0
    )
    comm.barrier()
    assert (root / "cmp" / "frame_force.png").is_file()
    assert (root / "cmp" / "bias_error_map.png").is_file()
    # --max-dofs 1: on the mesh the bias data were made on, without the mesh selection (its
    # h/2 check would refine towards a mesh finer than the data's own; tests/test_mesh_choice)
    assert (
        main(
            [
                "diagnose",
                str(root / "bias"),
                str(root / "frame"),
                "--terms",
                "fibre_stretch,shear",
                "--h",
                "4",
                "--confirm",
                "1",
                "--max-effects",
                "1",
                "--max-dofs",
                "1",
                "--out",
                str(root / "diag"),
            ]
        )
        == 0
    )
    comm.barrier()
    d = json.loads((root / "diag" / "diagnosis.json").read_text())
    assert [e["experiment"] for e in d["final"]["misfit"]["experiments"]] == ["bias", "frame"]
    assert d["verdict"] is None  # the data hold no effect beyond the baseline: no false alarm


def test_boundary_data_after_the_solver_is_an_error():
    """Boundary data are compiled into the solver when it is built; adding more afterwards would
    be silently ignored, so it raises."""
    from fabricsurf.experiments.bias_extension import BiasExtension

    truth = {k: MATERIAL[k] for k in ("fibre_stretch", "shear")}
    b = BiasExtension(full_model(list(truth), truth), 40.0, 20.0, 10.0)
    with pytest.raises(RuntimeError, match="already built"):
        b.problem.fix("top", (0.0, None))
