"""Version-guarded access to what the pinned PETSc and UFL do not offer publicly.

Everything here touches private API or a C library directly; each function checks that what it
relies on exists and fails (or falls back) with a message that names the version, so that a
newer FEniCSx stack breaks loudly here rather than silently elsewhere.
"""

from __future__ import annotations

import ctypes
import glob
import os
from functools import cache

import ufl
from petsc4py import PETSc


@cache
def _petsc_library():
    """The PETSc shared library petsc4py loaded, found through the process's memory map (or
    PETSC_DIR/PETSC_ARCH), with the two domain-error calls petsc4py 3.18 lacks; None if absent."""
    paths = []
    if os.path.exists("/proc/self/maps"):
        with open("/proc/self/maps") as f:
            paths = [ln.split()[-1] for ln in f if "libpetsc" in ln and ".so" in ln]
    if not paths:
        import petsc4py

        cfg = petsc4py.get_config()
        paths = glob.glob(os.path.join(cfg["PETSC_DIR"], cfg["PETSC_ARCH"], "lib", "libpetsc*.so*"))
    try:
        lib = ctypes.CDLL(paths[0])
        for fn in (lib.SNESSetFunctionDomainError, lib.SNESSetJacobianDomainError):
            fn.argtypes = [ctypes.c_void_p]
        return lib
    except (IndexError, OSError, AttributeError):
        return None


def set_domain_error(snes: PETSc.SNES, which: str) -> bool:
    """Tell SNES that the last function (``which = "function"``) or Jacobian (``"jacobian"``)
    evaluation left the energy's domain, so that its line search backtracks. Uses petsc4py's
    method where it has one (newer than 3.18), else the C call; returns False if neither exists
    (SNES then sees the non-finite values themselves and diverges, which the load stepper cuts)."""
    method = {"function": "setFunctionDomainError", "jacobian": "setJacobianDomainError"}[which]
    if hasattr(snes, method):
        getattr(snes, method)()
        return True
    lib = _petsc_library()
    if lib is None:
        return False
    getattr(lib, f"SNES{method[0].upper()}{method[1:]}")(snes.handle)
    return True


def _require(obj, attr: str, what: str) -> None:
    if not hasattr(obj, attr):
        owner = getattr(obj, "__name__", type(obj).__name__)
        raise RuntimeError(
            f"{what} relies on {owner}.{attr} of UFL 2022 (installed: "
            f"UFL {ufl.__version__}); check fabricsurf/discretise/jit_keys.py "
            "against this version"
        )


def set_coordinate_element(domain: ufl.Mesh, element: ufl.FiniteElementBase) -> None:
    """Replace a UFL mesh's coordinate element in place (UFL 2022 has no public setter)."""
    _require(domain, "_ufl_coordinate_element", "marking a mesh equispaced")
    domain._ufl_coordinate_element = element


def raise_constant_count(floor: int) -> None:
    """Make the next ``ufl.Constant`` count at least ``floor`` (UFL 2022's global counter)."""
    _require(ufl.Constant, "_globalcount", "stable Constant numbering")
    if ufl.Constant._globalcount < floor:
        ufl.Constant._globalcount = floor


def raise_jit_wait(seconds: int) -> None:
    """Make dolfinx's default JIT ``timeout`` (how long a process waits for a kernel that
    another process is compiling into the shared cache) at least ``seconds``: dolfinx 0.5 keeps
    the defaults in ``dolfinx.jit.DOLFINX_DEFAULT_JIT_PARAMETERS``, which a user's
    dolfinx_jit_parameters.json and a form's own ``jit_params`` still override."""
    from dolfinx import jit

    defaults = getattr(jit, "DOLFINX_DEFAULT_JIT_PARAMETERS", None)
    if not isinstance(defaults, dict) or "timeout" not in defaults:
        raise RuntimeError(
            "the JIT wait relies on dolfinx.jit.DOLFINX_DEFAULT_JIT_PARAMETERS['timeout'] of "
            "dolfinx 0.5; check fabricsurf/discretise/jit_keys.py against this version"
        )
    value, doc = defaults["timeout"]
    if value < seconds:
        defaults["timeout"] = (seconds, doc)
