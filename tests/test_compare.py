"""Forward model at the data: tangent sensitivities vs finite differences of the load path,
zero misfit on exact data, points outside the mesh reported, the compare CLI."""

import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.cli import main
from fabricsurf.inverse.contract.data import write_experiment
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.forward.misfit import misfit
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy

TRUTH = {
    "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
    "shear": {"k_s": 0.5},
    "geodesic_bending": {"A_g": 10.0},
}


def experiment():
    exp = sy.template(40.0, 20.0, [0.8, 1.6], sy.grid_points(40.0, 20.0, 6, 3))
    return sy.continuum_data(exp, full_model(list(TRUTH), TRUTH), h=5.0)


def test_sensitivities_match_finite_differences():
    exp = experiment()
    fm = ForwardModel(exp, full_model(list(TRUTH), TRUTH), h=5.0)
    p = fm.run(sens=True)
    v0 = fm.values()
    for k in range(len(v0)):
        dp = 1e-4 * max(v0[k], 1.0)
        v = v0.copy()
        v[k] += dp
        fm.set_values(v)
        q = fm.run()
        fm.set_values(v0)
        scale = max(np.abs(p.du[:, :, k]).max(), 1e-12)
        assert np.abs((q.u - p.u) / dp - p.du[:, :, k]).max() < 1e-2 * scale, fm.names[k]
        assert np.allclose((q.force - p.force) / dp, p.dforce[:, k], rtol=1e-2, atol=1e-6)


def test_misfit_zero_on_exact_data_and_outside_points():
    exp = experiment()
    fm = ForwardModel(exp, full_model(list(TRUTH), TRUTH), h=5.0)
    m = misfit(exp, fm.run())
    assert m["field_rms"] < 1e-9 and m["force_rms"] < 1e-8 and m["points_outside"] == 0
    exp.X[0] = (-5.0, 1.0)  # bypasses the loader's validation on purpose
    m = misfit(exp, fm.run())
    assert m["points_outside"] == 1 and np.isfinite(m["combined"])


def test_compare_cli(tmp_path):
    comm = MPI.COMM_WORLD
    exp = sy.add_noise(experiment(), 0.01, 0.01, 21)
    root = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    if comm.rank == 0:
        write_experiment(root / "data", exp)
        (root / "p.json").write_text(json.dumps(TRUTH))
    comm.barrier()
    assert (
        main(
            [
                "compare",
                str(root / "data"),
                "--params",
                str(root / "p.json"),
                "--out",
                str(root / "out"),
                "--h",
                "5",
            ]
        )
        == 0
    )
    comm.barrier()
    m = json.loads((root / "out" / "misfit.json").read_text())
    assert 0.7 < m["combined"] < 1.3 and len(m["experiments"][0]["per_step"]) == 2
    assert m["provenance"]["params"]["geodesic_bending"] == TRUTH["geodesic_bending"]
    used = m["provenance"]["discretisation"][exp.name]  # what the run got, not what was asked
    assert used["h_requested"] == 5.0 and 0 < used["h_used"] <= 5.0 and used["mesh_kind"]
    for f in ("error_map.png", "force.png", "error_vs_step.png", "per_point.csv"):
        assert (root / "out" / f).is_file()
    assert (
        main(["compare", str(root / "nodata"), "--terms", "shear", "--out", str(root / "o2")]) == 2
    )
