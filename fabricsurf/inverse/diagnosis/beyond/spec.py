"""One feature beyond the vocabulary: its density as Python source and as text, and the Term
source a user pastes into a module of their own; the kinematic quantities the features use
beyond :mod:`fabricsurf.model.kinematics`."""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

import ufl

from fabricsurf.model.kinematics import Kinematics, second_derivative


def shear_angle_gradient(kin: Kinematics, A):
    """∂_A γ = A·∇γ: the shear angle's derivative along the reference direction A, exact from F
    and the second gradient H (γ = θ0 − acos c, c = FL·FM/(λμ), so ∂_A γ = ∂_A c / sin θ)."""
    a, b = kin.F * kin.L, kin.F * kin.M
    lam, mu = kin.lam, kin.mu
    ra, rb = second_derivative(kin.H, kin.L, A), second_derivative(kin.H, kin.M, A)
    c = ufl.dot(a, b) / (lam * mu)
    dc = (ufl.dot(ra, b) + ufl.dot(a, rb)) / (lam * mu) - c * (
        ufl.dot(a, ra) / lam**2 + ufl.dot(b, rb) / mu**2
    )
    return dc / ufl.sqrt(1 - c**2)


@dataclass(frozen=True)
class FeatureSpec:
    """One feature: W = sign·coef·k·f(kin), f given as Python source (``expr``, reading ``kin``)
    and as text (``formula``)."""

    name: str
    formula: str
    expr: str
    reason: str
    coef: str = "0.5"
    coef_text: str = "½"
    sign: int = 1
    unit: str = "N/mm"
    order: int = 1
    in_plane: bool = True
    imports: tuple[str, ...] = ()

    @property
    def energy(self) -> str:
        """The density as text, e.g. "−½k·γ²((λ−1)+(μ−1))"."""
        return f"{'−' if self.sign < 0 else ''}{self.coef_text}k·{self.formula}"

    @property
    def proportional_to(self) -> str:
        """The form the outcome names: "γ²((λ−1)+(μ−1))", "−γ³"."""
        return f"{'−' if self.sign < 0 else ''}{self.formula}"

    @property
    def class_name(self) -> str:
        return "".join(w.capitalize() for w in self.name.split("_"))

    @property
    def source(self) -> str:
        """A user module defining the feature as a Term of one's own (docs/usage.md, "Adding
        your own effect"): paste it into a file and pass it to ``--effects``."""
        coef = f"{'-' if self.sign < 0 else ''}{self.coef}"
        doc = "\n    ".join(textwrap.wrap(f"{self.energy}: {self.reason}.", 88))
        third = "".join(f"{x}\n" for x in self.imports if not x.startswith("from fabricsurf"))
        ours = "".join(f"{x}\n" for x in self.imports if x.startswith("from fabricsurf"))
        flags = ("" if self.order == 1 else "    order: ClassVar[int] = 2\n") + (
            "" if self.in_plane else "    in_plane: ClassVar[bool] = False\n"
        )
        ret = f'        return {coef} * p["k"] * ({self.expr})'
        if len(ret) > 99:
            ret = f'        return {coef} * p["k"] * (\n            {self.expr})'
        return (
            f'"""{self.energy}: found by fabricsurf\'s search beyond the vocabulary."""\n'
            "from dataclasses import dataclass\nfrom typing import ClassVar\n\n"
            + (f"{third}\n" if third else "")
            + f"from fabricsurf import Term\n{ours}\n\n"
            f"@dataclass\nclass {self.class_name}(Term):\n"
            f'    """{doc}"""\n\n'
            "    k: float = 1.0\n"
            f'    name: ClassVar[str] = "{self.name}"\n'
            f'    units: ClassVar[dict[str, str]] = {{"k": "{self.unit}"}}\n{flags}\n'
            f"    def density(self, kin, p):\n{ret}\n"
        )
