"""The bias-extension test as an experiment plug-in (the ``bias_extension`` value of
``[loading] test``): its options, the checks of a specimen and the set-up of
:class:`~fabricsurf.experiments.bias_extension.BiasExtension` on the data's specimen, with the
grip depth held beyond the free length. Apart from the test itself (bias_extension.py), which a
user runs without any data contract."""

from __future__ import annotations

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

    def set_load(self, t: float) -> None:
        self.bias.set_load(t)

    def reaction_weight(self) -> fem.Function:
        return self._w
