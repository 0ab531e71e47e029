"""The forming indicators of the hemisphere plug-in (experiments/hemisphere.py): where the sheet
wrinkles and where it is sheared beyond the locking angle.

Wrinkling (:class:`Wrinkling`, the plug-in's ``wrinkle`` output and area): the unheld flange
strip where the least principal value of the smoothed membrane force is more compressive than
the strip's plate-buckling force. The curvature flag of :class:`Indicators` (a fibre in compression,
T < −T_w, that bends more sharply than κ_w) is kept for comparison only: curvature cannot tell a
wrinkle (about 0.02/mm) from the bend over the die's lip (0.5/mm), and on finer meshes it marks
more (docs/forming.md). Beyond locking: |γ| > γ_lock. The indicators are 0/1 fields of the
reference blank; their integrals give the area that wrinkles and the area beyond locking.

The thresholds (N_cr, its factor and the smoothing length; T_w, κ_w, γ_lock) are
``fem.Constant``s: a form holding them is compiled once for all values (plain numbers in the
form would compile the two forms again for each new punch radius, whose 1/R is the default
κ_w). What the indicators mark is compared with the flange's out-of-plane amplitude and a
buckling estimate in fabricsurf/verification/wrinkling.py
(docs/forming.md, "Wrinkling").
"""

from __future__ import annotations

import math

import dolfinx.fem.petsc  # noqa: F401 (fem.petsc)
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from fabricsurf.discretise.resources import Owner, destroy, release_vectors
from fabricsurf.model.kinematics import l_dir, m_dir


class Indicators:
    """The wrinkling and beyond-locking indicators (module docstring), their thresholds
    ``fem.Constant``s on ``msh``: ``tension`` T_w (N/mm), ``curvature`` κ_w (1/mm),
    ``locking`` γ_lock (rad). Set a threshold's ``value`` to change it without recompiling."""

    def __init__(self, msh, tension: float, curvature: float, locking_deg: float) -> None:
        self.tension = fem.Constant(msh, float(tension))
        self.curvature = fem.Constant(msh, float(curvature))
        self.locking = fem.Constant(msh, math.radians(locking_deg))

    @classmethod
    def from_options(cls, msh, options: dict) -> Indicators:
        """From the plug-in's ``[tooling]`` options (forming_options.parse)."""
        return cls(
            msh,
            options["wrinkle_tension"],
            options["wrinkle_curvature"],
            options["locking_angle_deg"],
        )

    def wrinkle(self, kin, tensions: dict):
        """1 where a fibre is compressed beyond T_w and bends beyond κ_w, else 0 (UFL);
        ``tensions`` holds ``tension_l`` and ``tension_m`` (EnergyForm.tension_fields)."""
        flags = [
            ufl.conditional(
                ufl.And(
                    ufl.lt(tensions[f"tension_{f}"], -self.tension), ufl.gt(abs(K), self.curvature)
                ),
                1.0,
                0.0,
            )
            for f, K in (("l", kin.K_L), ("m", kin.K_M))
        ]
        return ufl.max_value(*flags)

    def locked(self, kin):
        """1 where |γ| > γ_lock, else 0 (UFL)."""
        return ufl.conditional(ufl.gt(abs(kin.gamma), self.locking), 1.0, 0.0)


PLATE_K_SIMPLY_SUPPORTED = 4.0
"""Buckling coefficient of a long plate strip compressed along its length with simply
supported edges, N_cr = k π² D / b² (Timoshenko & Gere 1961, §9.2)."""


def bending_stiffness(model: list) -> float:
    """min over α of D(α) = k_b (cos⁴α + sin⁴α) + k_t cos²α sin²α (N·mm): the least bending
    stiffness of the fabric model for a cylindrical bend at angle α to a fibre of an orthogonal
    net (NormalBending, Twist: K_L = κ cos²α, K_M = κ sin²α, T = κ cos α sin α)."""
    values = {t.name: t.values() for t in model}
    k_b = values.get("normal_bending", {}).get("k_b", 0.0)
    k_t = values.get("twist", {}).get("k_t", 0.0)
    a = np.linspace(0.0, 0.5 * math.pi, 91)
    c2, s2 = np.cos(a) ** 2, np.sin(a) ** 2
    return float((k_b * (c2**2 + s2**2) + k_t * c2 * s2).min())


def membrane_parts(kin, tensions: dict) -> tuple:
    """(T_l, T_m, l·m): the fibre tensions (N/mm, UFL) and the cosine of the fibres' angle,
    which define the fibres' membrane force N = T_l l⊗l + T_m m⊗m (the shear term's stress
    left out)."""
    return (
        tensions["tension_l"],
        tensions["tension_m"],
        ufl.dot(l_dir(kin.F, kin.L), m_dir(kin.F, kin.M)),
    )


def least_principal(T_l, T_m, c):
    """The lesser principal value of N = T_l l⊗l + T_m m⊗m in the sheet's tangent plane (N/mm;
    numpy arrays): with c = l·m, tr N = T_l + T_m and det N = T_l T_m (1 − c²), so
    N_min = ½ tr N − √(¼ (T_l − T_m)² + T_l T_m c²); c is clipped to [−1, 1]."""
    c = np.clip(c, -1.0, 1.0)
    disc = 0.25 * (T_l - T_m) ** 2 + T_l * T_m * c**2  # = (½ tr N)² − det N ≥ 0
    return 0.5 * (T_l + T_m) - np.sqrt(np.maximum(disc, 0.0))


class Wrinkling(Owner):
    """Where the unheld flange buckles (docs/forming.md, "Wrinkling"): in the strip between the
    end of the die's lip and the holder's full pressure, at the current distance σ from the
    opening's outline r_d ≤ σ < r_d + b, b = 2 r_d (a circle's radii R_o + r_d ≤ ρ < R_o + 3 r_d;
    forming_tools.Tools.holder_weight; under a holder given as a surface, from r_d to where its
    pressure is full), the lesser principal value of the smoothed membrane force is below
    −``factor`` N_cr, N_cr = 4π²D/b² the plate-buckling force of the strip
    (Timoshenko & Gere 1961, §9.2) with D the model's least bending stiffness (:func:`
    bending_stiffness`, at the model's current moduli).

    The force is smoothed over the length ``length`` (a Helmholtz filter ν − ℓ²Δν = f on the
    reference blank, P1: a wrinkle is a wave of the strip's width, not a quadrature point)
    before its least principal value is taken: T_l, T_m and l·m each, then N_min at every node
    (:func:`least_principal`). A plate buckles under its mean membrane force, and N_min is
    concave in the tensions: smoothing N_min itself biased it towards compression wherever the
    tensions oscillate from point to point (stiff fibres: ±8 N/mm about a mean near zero in the
    forming demo's strip), and marked the whole strip where the mean force was tensile.

    ``factor`` (default 1), ``buckling_force`` (N_cr, N/mm, set by :meth:`update`) and
    ``length`` (mm, default r_d) are fem.Constants; :meth:`update` recomputes N_cr and the
    smoothed force at the current state (the plug-in calls it after every converged step);
    :attr:`mark` is the 0/1 indicator (UFL)."""

    def __init__(self, msh, r, kin, tensions: dict, tools, model: list, dx) -> None:
        self.comm, self.model, self.tools = msh.comm, model, tools
        self.factor = fem.Constant(msh, 1.0)
        self.buckling_force = fem.Constant(msh, self.plate_buckling_force())
        self.length = fem.Constant(msh, float(tools.lip.value))
        V = fem.FunctionSpace(msh, ("CG", 1))
        self.smoothed = fem.Function(V, name="least_membrane_force")
        self._parts = [fem.Function(V) for _ in range(3)]
        nu, w = ufl.TrialFunction(V), ufl.TestFunction(V)
        self._a = fem.form((nu * w + self.length**2 * ufl.inner(ufl.grad(nu), ufl.grad(w))) * dx)
        self._L = [fem.form(f * w * dx) for f in membrane_parts(kin, tensions)]
        self._A = fem.petsc.create_matrix(self._a)
        self._b = fem.petsc.create_vector(self._L[0])
        self._ksp = PETSc.KSP().create(self.comm)
        self._ksp.setOperators(self._A)
        self._ksp.setType("cg")
        self._ksp.getPC().setType("jacobi")
        self._ksp.setTolerances(rtol=1e-12, atol=1e-14, max_it=1000)
        self._filter_length = None  # the length the filter matrix was assembled with
        sigma = tools.opening.sigma(r)
        if tools.press is None:
            short = ufl.lt(sigma, 3.0 * tools.lip)
        else:  # a holder given as a surface: short of its full pressure
            short = ufl.lt(tools.holder_weight(r), 1.0)
        strip = ufl.And(ufl.ge(sigma, tools.lip), short)
        threshold = self.factor * self.buckling_force
        self.mark = ufl.conditional(ufl.And(strip, ufl.lt(self.smoothed, -threshold)), 1.0, 0.0)

    def plate_buckling_force(self) -> float:
        """N_cr = 4π²D/b², b = 2 r_d (N/mm), at the model's current moduli."""
        b = 2.0 * float(self.tools.lip.value)
        return PLATE_K_SIMPLY_SUPPORTED * math.pi**2 * bending_stiffness(self.model) / b**2

    def threshold(self) -> float:
        """The compression that marks (N/mm): ``factor`` × N_cr."""
        return float(self.factor.value) * float(self.buckling_force.value)

    def update(self) -> None:
        """N_cr at the current moduli, and the least principal value of the smoothed membrane
        force at the current state (collective). The filter's matrix lives on the reference
        blank: it is assembled again only when ``length`` has changed."""
        self.buckling_force.value = self.plate_buckling_force()
        if self._filter_length != float(self.length.value):  # on the reference blank: once
            self._A.zeroEntries()
            fem.petsc.assemble_matrix(self._A, self._a)
            self._A.assemble()
            self._filter_length = float(self.length.value)
        for L, part in zip(self._L, self._parts):
            with self._b.localForm() as loc:
                loc.set(0.0)
            fem.petsc.assemble_vector(self._b, L)
            self._b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            self._ksp.solve(self._b, part.vector)
            part.x.scatter_forward()
        self.smoothed.x.array[:] = least_principal(*(p.x.array for p in self._parts))

    def _release(self) -> None:
        destroy(self._ksp, self._A, self._b)
        release_vectors(self.smoothed, *self._parts)
