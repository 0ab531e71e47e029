"""docs/contracts.md: the measurement directory loader accepts good data and rejects each bad-input
class with one message naming the file, row (line) or key, and the problem."""

import re

import numpy as np
import pytest
from mpi4py import MPI

from fabricsurf.experiments.base import PluginSetup
from fabricsurf.inverse.contract.data import (
    DataError,
    Experiment,
    load_experiment,
    write_experiment,
)


def good_experiment() -> Experiment:
    X = np.array([[10.0, 5.0], [20.0, 10.0], [30.0, 15.0]])
    steps = np.array([1, 2])
    field_step = np.repeat(steps, len(X))
    u = np.column_stack([np.linspace(0, 1, 6), np.linspace(0, -0.1, 6)])
    setup = PluginSetup("bias_extension", 40.0, 20.0, (45.0, -45.0), {"clamp": "gradient"})
    return Experiment(
        "t",
        setup,
        steps,
        np.array([1.0, 2.0]),
        np.array([0.5, 1.1]),
        field_step,
        np.vstack([X, X]),
        u,
        noise_std=0.01,
    )


@pytest.fixture
def good(tmp_path):
    d = tmp_path / f"exp{MPI.COMM_WORLD.rank}"
    write_experiment(d, good_experiment())
    return d


def edit(path, old, new):
    path.write_text(path.read_text().replace(old, new, 1))


def reject(d, *patterns):
    with pytest.raises(DataError) as e:
        load_experiment(d)
    msg = str(e.value)
    for p in patterns:
        assert re.search(p, msg), (p, msg)
    return msg


def test_roundtrip_and_units(good):
    exp = load_experiment(good)
    ref = good_experiment()
    assert np.allclose(exp.u, ref.u) and np.allclose(exp.X, ref.X)
    assert np.allclose(exp.force, ref.force) and exp.noise_std == 0.01
    edit(good / "experiment.toml", 'length = "mm"', 'length = "m"')
    edit(good / "experiment.toml", 'force = "N"', 'force = "kN"')
    edit(good / "experiment.toml", "length = 40.0", "length = 0.04")
    edit(good / "experiment.toml", "width = 20.0", "width = 0.02")
    (good / "field.csv").write_text("step,X,Y,ux,uy\n1,0.01,0.005,0.001,0\n")
    (good / "force.csv").write_text("step,displacement,force\n1,0.001,0.5\n2,0.002,1.1\n")
    exp = load_experiment(good)
    assert np.isclose(exp.length, 40.0) and np.allclose(exp.X, [[10.0, 5.0]])
    assert np.allclose(exp.u, [[1.0, 0.0]]) and np.isclose(exp.force[1], 1100.0)
    assert np.allclose(exp.path, [1.0, 2.0])
    assert np.isclose(exp.noise_std, 10.0)


def test_missing_file(good):
    (good / "force.csv").unlink()
    reject(good, "force.csv", "not found")
    (good / "experiment.toml").unlink()
    reject(good, "experiment.toml", "not found")


def test_missing_column(good):
    edit(good / "field.csv", "ux", "vx")
    reject(good, "field.csv", "missing column", "ux")


def test_missing_key(good):
    edit(good / "experiment.toml", "width = 20.0\n", "")
    reject(good, "experiment.toml", r"\[specimen\] width")


def test_nan(good):
    lines = (good / "field.csv").read_text().splitlines()
    lines[3] = ",".join(lines[3].split(",")[:3] + ["nan", "0.0"])
    (good / "field.csv").write_text("\n".join(lines) + "\n")
    reject(good, "field.csv line 4", "ux", "not a finite number")


def test_unknown_unit(good):
    edit(good / "experiment.toml", 'length = "mm"', 'length = "cm"')
    reject(good, "experiment.toml", r"\[units\] length", "'cm'")


def test_point_outside(good):
    edit(good / "field.csv", "\n2,30.0,15.0,", "\n2,45.0,15.0,")
    reject(good, "field.csv line 7", "outside the specimen")


def test_duplicate_rows(good):
    edit(good / "field.csv", "\n2,20.0,10.0,", "\n2,10.0,5.0,")
    reject(good, "field.csv line 6", "duplicate", "line 5")
    write_experiment(good, good_experiment(), overwrite=True)
    edit(good / "force.csv", "\n2,", "\n1,")
    reject(good, "force.csv line 3", "duplicate step 1")


def test_step_mismatch(good):
    edit(good / "force.csv", "\n2,", "\n3,")
    reject(good, "field.csv line 5", "step 2 does not appear")


def test_atomic_write(tmp_path):
    d = tmp_path / f"w{MPI.COMM_WORLD.rank}"
    write_experiment(d, good_experiment())
    with pytest.raises(FileExistsError):
        write_experiment(d, good_experiment())
    bad = good_experiment()
    bad.steps = None  # fails while writing: the existing directory is untouched
    with pytest.raises(TypeError):
        write_experiment(d, bad, overwrite=True)
    assert load_experiment(d).name == "t"
    assert sorted(p.name for p in tmp_path.iterdir()) == [d.name]


def test_spreadsheet_bom_and_unit_types(good):
    """A UTF-8 byte-order mark (spreadsheet export) is accepted; a unit given as a list is a
    DataError naming the key, not a crash."""
    f = good / "field.csv"
    f.write_bytes(b"\xef\xbb\xbf" + f.read_bytes())
    assert len(load_experiment(good).X) == 6
    edit(good / "experiment.toml", 'length = "mm"', 'length = ["mm"]')
    reject(good, "experiment.toml", "length")


def test_compare_rejects_terms_outside_vocabulary():
    from fabricsurf.inverse.forward.runs import ForwardModel
    from fabricsurf.model.materials import bipantographic

    with pytest.raises(ValueError, match="not in the vocabulary"):
        ForwardModel(good_experiment(), bipantographic())


def test_first_duplicate_is_the_earliest_repeat():
    """The vectorised duplicate search names the same pair of rows as a scan in file order
    (the message's two line numbers), on random small tables with many repeats."""
    from fabricsurf.inverse.contract.checks import _first_duplicate

    def scan(keys):
        seen = {}
        for i, k in enumerate(map(tuple, keys)):
            if k in seen:
                return seen[k], i
            seen[k] = i
        return None

    rng = np.random.default_rng(1)
    for _ in range(2000):
        keys = rng.integers(0, 3, (rng.integers(0, 12), rng.integers(1, 4))).astype(float)
        assert _first_duplicate(keys) == scan(keys), keys
