"""Synthetic forming data (the hemisphere test, docs/contracts.md): the punch force against the
stroke and the shear angles at points of the formed part, as optical measurement gives them.

The data are made with a model richer than the one a diagnosis starts from (a hidden effect)
by the forward model itself (fabricsurf.inverse.forward.runs), plus Gaussian noise of known
standard deviation: :func:`hemisphere_template` lays out the experiment, :func:`forming_data`
fills in the model's values, :func:`add_forming_noise` the noise.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.inverse.contract.experiment import Experiment, template
from fabricsurf.model.terms import Term


def part_points(blank: float, radius: float, n: int) -> np.ndarray:
    """Points of the formed part as an optical system sees it: an n × n grid over the square
    that holds the die opening (radius ``radius``, centred on the blank of side ``blank``),
    kept where inside the opening; in the data's frame (origin at the blank's corner), on all
    four quarters, none on the mid-lines (n even)."""
    c = 0.5 * blank
    g = np.linspace(-radius, radius, n)
    pts = np.array([(x, y) for x in g for y in g if x * x + y * y < radius**2])
    return pts + c


def hemisphere_template(
    blank: float,
    tooling: dict,
    strokes,
    points: np.ndarray,
    angles: tuple[float, float] = (45.0, -45.0),
    name: str = "hemisphere",
    shear_steps=None,
) -> Experiment:
    """A hemisphere experiment with zero measurements: the punch force at every stroke of
    ``strokes`` and the shear angle at ``points`` (n×2, the data's frame) at the steps
    ``shear_steps`` (default: the last). ``tooling``: the [tooling] keys (mm, N)."""
    opts = HemispherePlugin.parse_options({"tooling": dict(tooling)}, 1.0, "tooling")
    exp = template(
        blank,
        blank,
        strokes,
        np.zeros((0, 2)),
        angles,
        name=name,
        test="hemisphere",
        options=opts,
        force=True,
    )
    steps = exp.steps[-1:] if shear_steps is None else np.asarray(shear_steps, dtype=np.int64)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    exp.shear_step = np.repeat(steps, len(pts))
    exp.shear_X = np.tile(pts, (len(steps), 1))
    exp.shear = np.zeros(len(exp.shear_step))
    return exp


def forming_data(
    exp: Experiment, model: list[Term], h: float, comm: MPI.Comm = MPI.COMM_WORLD
) -> Experiment:
    """Fill ``exp`` with the punch force and shear angles of ``model`` on a mesh of size h."""
    from fabricsurf.inverse.forward.runs import ForwardModel

    with ForwardModel(exp, model, h=h, comm=comm) as fm:
        pred = fm.run()
    if exp.has_shear and not np.isfinite(pred.shear).all():
        raise RuntimeError("synthetic forming data: a shear point lies outside the blank")
    exp.force = pred.force.copy()
    exp.shear = pred.shear.copy()
    return exp


def add_forming_noise(
    exp: Experiment, force_noise_std: float, shear_noise_deg: float, seed: int
) -> Experiment:
    """Independent Gaussian noise on every force (N) and shear angle (deg), the same draw on
    every rank; the noise levels are recorded in the data."""
    rng = np.random.default_rng(seed)
    exp.force = exp.force + rng.normal(0.0, force_noise_std, exp.force.shape)
    exp.shear = exp.shear + rng.normal(0.0, shear_noise_deg, exp.shear.shape)
    exp.force_noise_std, exp.shear_noise_deg = float(force_noise_std), float(shear_noise_deg)
    return exp
