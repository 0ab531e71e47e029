"""An experiment in memory: its set-up and its measurements, in mm and N."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fabricsurf.experiments.base import PluginSetup


@dataclass
class Experiment:
    """One experiment in mm and N.

    ``steps``, ``path`` (load-path value: a displacement in mm, or a factor), ``force`` (the
    measured reaction, or None): one entry per load step, sorted by step number.
    ``field_step``, ``X`` (n×2), ``u`` (n×2 or n×3): the full-field rows (n = 0: force only).
    ``shear_step``, ``shear_X``, ``shear``: measured shear angles at points (a formed part).
    """

    name: str
    setup: PluginSetup
    steps: np.ndarray
    path: np.ndarray
    force: np.ndarray | None = None
    field_step: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    X: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    u: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    noise_std: float | None = None
    force_noise_std: float | None = None
    source: dict = field(default_factory=dict)
    shear_step: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    shear_X: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    shear: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Measured shear angles (deg) at points ``shear_X`` (the specimen's frame, mm) of steps
    ``shear_step`` (none: no shear data; docs/contracts.md, ``shear.csv``)."""
    shear_noise_deg: float | None = None
    directory: str | None = None
    files: tuple[str, ...] = ()
    """The files read (experiment.toml, the field and force files), as given."""

    @property
    def test(self) -> str:
        return self.setup.test

    @property
    def length(self) -> float:
        return self.setup.length

    @property
    def width(self) -> float:
        return self.setup.width

    @property
    def fibre_angles_deg(self) -> tuple[float, float]:
        return self.setup.fibre_angles_deg

    @property
    def has_field(self) -> bool:
        return len(self.field_step) > 0

    @property
    def has_shear(self) -> bool:
        return len(self.shear_step) > 0

    @property
    def has_force(self) -> bool:
        return self.force is not None

    def step_rows(self, step: int) -> np.ndarray:
        """Indices of the field rows of one step."""
        return np.flatnonzero(self.field_step == step)

    def shear_rows(self, step: int) -> np.ndarray:
        """Indices of the shear rows of one step."""
        return np.flatnonzero(self.shear_step == step)


def template(
    length: float,
    width: float,
    displacements,
    points: np.ndarray,
    angles: tuple[float, float] = (45.0, -45.0),
    clamp: str = "gradient",
    name: str = "synthetic",
    test: str = "bias_extension",
    options: dict | None = None,
    force: bool = True,
) -> Experiment:
    """An Experiment with the geometry and loading filled in and zero measurements.

    ``displacements``: the load path (one value per step); ``points``: field points (may be
    empty: force only); ``force``: whether the test's reaction is measured."""
    d = np.asarray(displacements, float)
    steps = np.arange(1, len(d) + 1)
    opts = {"clamp": clamp} if options is None else dict(options)
    setup = PluginSetup(test, float(length), float(width), tuple(angles), opts)
    pts = np.asarray(points, float).reshape(-1, 2)
    return Experiment(
        name,
        setup,
        steps,
        d,
        np.zeros(len(d)) if force else None,
        np.repeat(steps, len(pts)),
        np.tile(pts, (len(d), 1)),
        np.zeros((len(d) * len(pts), 2)),
    )
