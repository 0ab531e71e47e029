"""A user's own effects, without editing the package (docs/usage.md, "Adding your own effect").

:func:`register_effect` (Python) and ``--effects FILE.py`` (command line, :func:`load_effects`)
check a user's Term subclass and add it to the registry :data:`~fabricsurf.model.terms.EFFECTS`;
it is then accepted wherever a built-in is (``--terms``, ``--params``, diagnose candidates,
``fabricsurf terms``). Checked before any solve:

* a name that is an identifier, not taken by a built-in or another registered effect;
* a unit for every modulus (``units``), and ``signed`` naming moduli only;
* a default for every field, so ``cls()`` is the term at its default moduli;
* a density **linear in its moduli**, which the exact sensitivities of fit and diagnose assume
  (dr/dp from one tangent solve per modulus, the candidates' scores at modulus 0): checked
  numerically, W(2p) = 2 W(p) and W(p + q) = W(p) + W(q) to :data:`LINEAR_RTOL`, on
  :data:`STATES` random kinematic states (F and H cellwise, one per cell of a small
  ``MPI.COMM_SELF`` mesh: the same on every rank). A shape parameter (an angle, a strain at
  which something saturates) belongs in ``options``, not among the moduli.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import inspect
import math
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from fabricsurf.model.term import Term
from fabricsurf.model.terms import EFFECTS

LINEAR_RTOL = 1e-10
"""Relative tolerance of the linearity check (round-off of a few operations per state)."""
STATES = 32
"""Random kinematic states of the linearity check (cells of its mesh)."""


def register_effect(cls: type[Term], origin: str | None = None) -> type[Term]:
    """Check ``cls`` (module docstring) and add it to the registry; returns ``cls``, so it can
    decorate the class. ``origin``: where it comes from, shown by ``fabricsurf terms``
    (default: its module's file, or its module's name)."""
    if origin is None:
        module = sys.modules.get(getattr(cls, "__module__", ""), None)
        origin = getattr(module, "__file__", None) or getattr(cls, "__module__", "?")
    if not (isinstance(cls, type) and issubclass(cls, Term)):
        raise ValueError(f"{origin}: {cls!r} is not a subclass of fabricsurf's Term")
    if cls.name in EFFECTS:
        EFFECTS.register(cls, origin)  # raises: the clash named with both origins
    _check_declarations(cls, origin)
    check_linear(cls, origin)
    return EFFECTS.register(cls, origin)


def _check_declarations(cls: type[Term], origin: str) -> None:
    """Units for every modulus, ``signed`` among the moduli, a default for every field."""
    params = cls.parameters()
    what = f"{origin}: effect '{cls.name}' ({cls.__name__})"
    if not params:
        raise ValueError(
            f"{what} has no modulus (a dataclass field that is not in "
            "``options``); declare it with @dataclass and a field per modulus"
        )
    missing = [p for p in params if not str(cls.units.get(p, "")).strip()]
    if missing:
        raise ValueError(
            f"{what}: no unit declared for {', '.join(missing)}; add "
            f'units: ClassVar[dict[str, str]] = {{"{missing[0]}": "N/mm"}} '
            "(N/mm first gradient, N·mm second)"
        )
    stray = [s for s in cls.signed if s not in params]
    if stray:
        raise ValueError(
            f"{what}: signed names {', '.join(stray)}, which are not its moduli "
            f"({', '.join(params)})"
        )
    try:
        cls()
    except Exception as e:  # the user's constructor: any failure is reported
        raise ValueError(
            f"{what}: cannot be made at its defaults ({type(e).__name__}: {e}); "
            "give every field a default"
        ) from None


def load_effects(paths: list[str | Path]) -> list[str]:
    """Import each file of ``paths`` and register its Term subclasses that have a ``name``
    (those it defines, not those it imports); returns their names. A file that cannot be read
    or imported, or that defines none, is refused with the file named."""
    names: list[str] = []
    for path in paths:
        module = _import_file(Path(path))
        found = [
            c
            for _, c in inspect.getmembers(module, inspect.isclass)
            if issubclass(c, Term) and c is not Term and c.__module__ == module.__name__ and c.name
        ]
        if not found:
            raise ValueError(
                f"--effects {path}: defines no subclass of fabricsurf's Term with "
                'a name (name: ClassVar[str] = "my_effect")'
            )
        for cls in found:
            names.append(register_effect(cls, str(path)).name)
    return names


@contextlib.contextmanager
def effects_from(paths: list[str | Path]) -> Iterator[list[str]]:
    """:func:`load_effects` for the duration of a ``with`` block (one command): the effects are
    unregistered at its end, so that a second command in the same process (a test, a notebook)
    may load the same file again."""
    before = set(EFFECTS.user_effects())
    try:
        yield load_effects(paths)
    finally:
        for name in EFFECTS.user_effects():
            if name not in before:
                EFFECTS.unregister(name)


def _import_file(path: Path):
    """The module of ``path``, under a name of its own (not importable by accident)."""
    if not path.is_file():
        raise ValueError(f"--effects {path}: no such file")
    if path.suffix != ".py":
        raise ValueError(f"--effects {path}: not a Python file (.py)")
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]
    name = f"fabricsurf_user_effects_{digest}_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the class is made
    try:
        spec.loader.exec_module(module)
    except Exception as e:  # the user's module: any failure is reported
        del sys.modules[name]
        raise ValueError(
            f"--effects {path}: cannot be imported ({type(e).__name__}: {e})"
        ) from None
    return module


def check_linear(cls: type[Term], origin: str) -> None:
    """Refuse a density that is not linear in its moduli (module docstring)."""
    what = f"{origin}: effect '{cls.name}' ({cls.__name__})"
    try:
        w = density_evaluator(cls())
    except Exception as e:  # the user's density: any failure is reported
        raise ValueError(
            f"{what}: its density cannot be evaluated ({type(e).__name__}: {e})"
        ) from None
    rng = np.random.default_rng(20240601)
    names = cls.parameters()
    p = dict(zip(names, rng.uniform(0.5, 2.0, len(names))))
    q = dict(zip(names, rng.uniform(0.5, 2.0, len(names))))
    wp, wq = w(p), w(q)
    checks = (
        ("W(2p) = 2 W(p)", w({k: 2 * v for k, v in p.items()}), 2 * wp),
        ("W(p + q) = W(p) + W(q)", w({k: p[k] + q[k] for k in names}), wp + wq),
    )
    for rule, lhs, rhs in checks:
        scale = np.max(np.abs(lhs) + np.abs(rhs), initial=0.0)
        err = np.max(np.abs(lhs - rhs), initial=0.0)
        if not (math.isfinite(err) and err <= LINEAR_RTOL * scale):
            raise ValueError(
                f"{what}: its density is not linear in its moduli "
                f"({', '.join(names)}): {rule} fails by {err / max(scale, 1e-300):.2g}"
                " relative; fit and diagnose assume W linear in each modulus (make "
                "shape parameters options, not moduli: docs/usage.md)"
            )


def density_evaluator(term: Term):
    """p ↦ the term's density W (one value per random state) at moduli p: one compiled form,
    the moduli as constants."""
    import ufl
    from dolfinx import fem

    from fabricsurf.model.kinematics import Kinematics, fibre_vectors
    from fabricsurf.model.pure_shear import cell_values, strip_mesh
    from fabricsurf.model.term_constants import TermConstants

    msh = strip_mesh(STATES // 2)
    V = fem.FunctionSpace(msh, ("DG", 0))
    f, g = (fem.Function(fem.VectorFunctionSpace(msh, ("DG", 0), dim=n)) for n in (6, 12))
    rng = np.random.default_rng(7)
    eye = np.tile([1.0, 0.0, 0.0, 1.0, 0.0, 0.0], STATES)  # F = I (3×2) + a perturbation
    f.x.array[:] = eye + rng.uniform(-0.2, 0.2, eye.size)
    g.x.array[:] = rng.uniform(-0.3, 0.3, g.x.array.size)
    F = ufl.as_matrix([[f[2 * i + a] for a in range(2)] for i in range(3)])
    H = ufl.as_tensor(
        [[[g[4 * i + 2 * a + b] for b in range(2)] for a in range(2)] for i in range(3)]
    )
    L, M = fibre_vectors(0.0, 90.0)
    kin = Kinematics(F, H, ufl.as_vector(L), ufl.as_vector(M))
    consts = TermConstants({p: fem.Constant(msh, 1.0) for p in term.parameters()})
    W = ufl.as_ufl(term.density(kin, consts))
    if isinstance(W, ufl.constantvalue.Zero):
        return lambda p: np.zeros(STATES)
    dx = ufl.dx(domain=msh, metadata={"quadrature_degree": 1})
    form = fem.form(W * ufl.TestFunction(V) * dx)

    def evaluate(p: dict[str, float]) -> np.ndarray:
        for name, v in p.items():
            consts.assign(name, float(v))
        return cell_values(form)

    return evaluate
