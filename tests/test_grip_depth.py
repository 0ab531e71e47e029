"""Grip depth as a nuisance parameter of the diagnosis (docs/diagnosis.md, "Grips of finite
depth"): data of a complete model whose grips hold 1.5 mm of each end.

The profile over 0, 1.5 and 3 mm must find 1.5 mm, where the baseline is at the noise level
(combined misfit ≤ 1.25, as tests/test_diagnose.py) while the wrong depths are not: 0 mm leaves
3 mm too much free length, 3 mm 3 mm too little, and the moduli cannot make up for the shear a
wrong free length imposes. With the depth taken as 0 mm, the same data give a false alarm: a
gradient effect (stretch or shear gradient, indistinguishable here) stiffens the layers at the
grips in place of the missing grip (significant; outcome "add stretch_gradient (still not
adequate)"; the misfits are in docs/diagnosis.md).
Model, moduli and noise as tests/test_diagnose.py (the same compiled forms).
"""

from pathlib import Path

from mpi4py import MPI

from fabricsurf.cli import main
from fabricsurf.inverse.contract.data import write_experiment
from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.synthetic import generate as sy

TERMS = {
    "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
    "shear": {"k_s": 0.5},
    "geodesic_bending": {"A_g": 15.0},
}
NOISE_LEVEL = 1.25
DEPTH = 1.5


def gripped_data(seed=17):
    """62 × 31 mm, grips 1.5 mm deep; the first and last point columns (x = 1.86 mm from the
    ends) lie between the true grip edge and the deepest candidate's (3 mm)."""
    pts = sy.grid_points(62.0, 31.0, 10, 5, margin=0.03)
    exp = sy.template(
        62.0, 31.0, [1.8, 3.6], pts, options={"clamp": "gradient", "grip_depth": DEPTH}
    )
    sy.continuum_data(exp, full_model(list(TERMS), TERMS), h=2.2)
    exp.setup.options["grip_depth"] = 0.0
    return sy.add_noise(exp, 0.01, 0.02, seed)


def run(exp, **kw):
    return diagnose(
        [exp],
        list(TERMS),
        h=4.4,
        params=TERMS,
        confirm=1,
        max_effects=1,
        check_discretisation=False,
        **kw,
    )


def test_grip_depth_profile_and_false_alarm_without_it():
    exp = gripped_data()
    d = run(exp, grip_depths=[0.0, DEPTH, 3.0])
    g = d.as_dict()["grip_depth"]
    prof = {q["depth_mm"]: q for q in g["profile"]}
    print(
        [(q["depth_mm"], q["misfit"], q["n"]) for q in g["profile"]],
        d.verdict,
        d.base_fit.misfit["combined"],
    )
    assert g["best_mm"] == DEPTH and d.verdict is None and d.adequate
    assert prof[DEPTH]["misfit"] <= NOISE_LEVEL < min(prof[0.0]["misfit"], prof[3.0]["misfit"])
    # the profile compares on the rows outside the 3 mm grips; the diagnosis uses all rows
    # outside the 1.5 mm ones: the two columns of 5 points × 2 steps × 2 components more
    assert d.base_fit.misfit["n"] - prof[DEPTH]["n"] == 2 * 5 * 2 * 2
    assert d.base_fit.misfit["combined"] <= NOISE_LEVEL

    d0 = run(exp)
    print(
        d0.base_fit.misfit["combined"],
        [(r["effect"], r["refit_misfit"], r["significant"]) for r in d0.ranking],
        d0.outcome(),
    )
    assert d0.base_fit.misfit["combined"] > NOISE_LEVEL
    assert d0.verdict in {"stretch_gradient", "shear_gradient"}


def test_bad_grip_depths_cli(tmp_path, capsys):
    comm = MPI.COMM_WORLD
    root = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    exp = sy.template(62.0, 31.0, [1.8], sy.grid_points(62.0, 31.0, 3, 2))
    if comm.rank == 0:
        write_experiment(root / "data", sy.add_noise(exp, 0.01, 0.02, 0))
    comm.barrier()
    for spec, says in (
        ("0,abc", "expected comma-separated depths"),
        ("0,-1", "≥ 0 mm"),
        ("0,20", "leaves less than half"),
    ):
        assert (
            main(
                [
                    "diagnose",
                    str(root / "data"),
                    "--terms",
                    "fibre_stretch,shear",
                    "--out",
                    str(root / "out"),
                    "--grip-depths",
                    spec,
                ]
            )
            == 2
        )
        out = capsys.readouterr().out
        if comm.rank == 0:
            assert f"--grip-depths {spec}" in out and says in out, out
    assert not (root / "out").exists()
