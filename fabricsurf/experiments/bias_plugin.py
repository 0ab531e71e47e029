"""The bias-extension test as an experiment plug-in (the ``bias_extension`` value of
``[loading] test``): its options, the checks of a specimen and the set-up of
:class:`~fabricsurf.experiments.bias_extension.BiasExtension` on the data's specimen, with the
grip depth held beyond the free length. Apart from the test itself (bias_extension.py), which a
user runs without any data contract."""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import ExperimentPlugin, PluginSetup, choice_option, number_option
from fabricsurf.experiments.bias_extension import CLAMPS, BiasExtension
from fabricsurf.experiments.bias_mesh import check_bias_angles, specimen_mesh
from fabricsurf.experiments.bias_variants import bias_variants
from fabricsurf.geometry.aligned import canonical_angles
from fabricsurf.geometry.specimen import shift_x
from fabricsurf.model.terms import Term


class BiasExtensionPlugin(ExperimentPlugin):
    """The bias-extension test as an experiment plug-in: rectangle length × width (x along the
    load), grips at x = 0 and x = length; load path: grip displacement along +x (mm); reaction:
    total grip reaction along x (N). Option ``[loading] clamp``: "gradient" (u = 0 and zero
    normal derivative at both grips, Barchiesi et al. 2020 eq. 7) or "position" (u only)."""

    name = "bias_extension"
    path_label = "grip displacement (mm)"
    reaction_label = "grip force (N)"
    keys = {
        "loading": {
            "clamp": "gradient | position (default gradient)",
            "grip_depth": "depth held by each grip beyond the free length (length "
            "units, default 0)",
        }
    }

    @classmethod
    def separating_variants(cls, setup: PluginSetup, path, first_gradient: bool) -> list:
        return bias_variants(setup, path, first_gradient)

    def __init__(
        self, setup: PluginSetup, model: list[Term], h: float, comm: MPI.Comm = MPI.COMM_WORLD
    ) -> None:
        super().__init__(setup, model, h, comm)
        depth = float(setup.options.get("grip_depth", 0.0))
        angles = canonical_angles(tuple(setup.fibre_angles_deg))
        check_bias_angles(angles, setup.length - 2 * depth, setup.width)
        specimen = specimen_mesh(
            setup.length - 2 * depth, setup.width, h, angles, comm, model=self.model
        )
        if depth:
            shift_x(specimen, depth)
        self.bias = BiasExtension(
            self.model,
            setup.length,
            setup.width,
            h,
            setup.options.get("clamp", "gradient"),
            tuple(setup.fibre_angles_deg),
            comm=comm,
            specimen=specimen,
        )
        self.discretisation = self.bias.discretisation
        self.problem, self.solver = self.bias.problem, self.bias.solver
        self.followers = self.bias.followers
        self.model = self.bias.model  # the terms its forms are built from
        self._w = fem.Function(self.problem.V)
        self._w.x.array[self.problem.component_dofs("grip", 0)] = 1.0

    @classmethod
    def parse_options(cls, tables: dict, length_scale: float, where: str) -> dict:
        depth = number_option(tables, "loading", "grip_depth", where, 0.0, positive=False)
        if depth < 0:
            raise DataError(f"{where}: [loading] grip_depth = {depth:g} must be ≥ 0")
        return {
            "clamp": choice_option(tables, "loading", "clamp", CLAMPS, "gradient", where),
            "grip_depth": depth * length_scale,
        }

    @classmethod
    def check_specimen(cls, setup: PluginSetup, where: str) -> None:
        if 2 * setup.options.get("grip_depth", 0.0) >= 0.5 * setup.length:
            raise DataError(
                f"{where}: [loading] grip_depth "
                f"{setup.options['grip_depth']:g} mm leaves less than half of the "
                f"{setup.length:g} mm specimen free"
            )
        if setup.width > setup.length:
            raise DataError(
                f"{where}: [specimen] width {setup.width:g} mm exceeds length "
                f"{setup.length:g} mm; the bias specimen has its long side along "
                "the load (x)"
            )
        try:
            check_bias_angles(
                canonical_angles(tuple(setup.fibre_angles_deg)),
                setup.length - 2 * setup.options.get("grip_depth", 0.0),
                setup.width,
            )
        except ValueError as e:
            raise DataError(
                f"{where}: [specimen] fibre_angles_deg = {list(setup.fibre_angles_deg)}: {e}"
            ) from None

    @classmethod
    def zone_distance(cls, setup: PluginSetup, X) -> np.ndarray:
        """Distance (mm) from the nearest grip (x = grip_depth, x = length − grip_depth) or
        boundary between the zones of the bias test: the fibre lines through the grips'
        corners, along either family, at any fibre angles (:func:`fibre_zones`)."""
        return fibre_zones(setup, X)[1]

    def set_load(self, t: float) -> None:
        self.bias.set_load(t)

    def reaction_weight(self) -> fem.Function:
        return self._w


def _exit(P: np.ndarray, d: np.ndarray, box: tuple[float, float, float, float]):
    """(t, on_clamp): how far the ray P + t·d (d a unit vector, P n×2) runs inside the box
    (x0, x1, 0, W) and whether it leaves through a grip (x = x0 or x1) rather than a free
    edge."""
    x0, x1, y0, y1 = box
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(d[0] > 0, (x1 - P[:, 0]) / d[0], (x0 - P[:, 0]) / d[0])
        ty = np.where(d[1] > 0, (y1 - P[:, 1]) / d[1], (y0 - P[:, 1]) / d[1])
    tx = np.where(abs(d[0]) > 1e-12, np.maximum(tx, 0.0), np.inf)
    ty = np.where(abs(d[1]) > 1e-12, np.maximum(ty, 0.0), np.inf)
    return np.minimum(tx, ty), tx <= ty


def fibre_zones(setup: PluginSetup, X) -> tuple[np.ndarray, np.ndarray]:
    """(zone, distance) of reference points ``X`` (n×2) of a bias specimen. The zone of a
    point of an inextensible net is fixed by how many of the two fibre lines through it reach
    a grip: both (2, zone A: held rigid), one (1, zone B: half the shear), none (0, zone C:
    the full shear; Cao et al. 2008 §5). The zones change across the fibre lines through the
    grips' corners, so the distance is to the nearest of those lines (clipped to the
    specimen) or to a grip; points in a grip have distance 0."""
    X = np.asarray(X, dtype=float).reshape(-1, 2)
    depth = float(setup.options.get("grip_depth", 0.0))
    box = (depth, setup.length - depth, 0.0, setup.width)
    dirs = [
        np.array([np.cos(np.radians(a)), np.sin(np.radians(a))]) for a in setup.fibre_angles_deg
    ]
    zone = np.zeros(len(X), dtype=int)
    for d in dirs:
        zone += (_exit(X, d, box)[1] | _exit(X, -d, box)[1]).astype(int)
    dist = np.maximum(np.minimum(X[:, 0] - box[0], box[1] - X[:, 0]), 0.0)
    corners = np.array([(box[0], 0.0), (box[0], box[3]), (box[1], 0.0), (box[1], box[3])])
    for Q in corners:
        for d in [s * v for v in dirs for s in (1.0, -1.0)]:
            t_end = float(_exit(Q[None, :], d, box)[0][0])
            if t_end <= 0.0:
                continue  # the line leaves the specimen at this corner
            t = np.clip((X - Q) @ d, 0.0, t_end)
            dist = np.minimum(dist, np.linalg.norm(X - (Q + t[:, None] * d), axis=1))
    return zone, dist
