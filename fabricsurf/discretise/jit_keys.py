"""Form cache keys that depend on the form only.

FFCx caches a compiled form under its UFL signature. Two behaviours of the pinned FFCx 0.5 and
UFL 2022 make the signature of one and the same form depend on what the process did before, so
that identical kernels were compiled again (once per key; the large second-gradient kernels
take minutes each). Both are neutralised here, before any of our forms is built; the tests are
in tests/test_jit_keys.py.
"""

import ufl
from dolfinx import mesh as dmesh

from fabricsurf.discretise.compat import raise_constant_count, set_coordinate_element

CONSTANT_COUNT_FLOOR = 10**6


def mark_equispaced(msh: dmesh.Mesh) -> dmesh.Mesh:
    """``msh`` with its P1 coordinate element marked equispaced, in place, before any form on it
    is compiled (a mesh from dolfinx's built-in constructors comes unmarked): FFCx 0.5 marks it
    on the first form it compiles, and the mark enters every later form's cache key, which then
    depends on the cache's state and on the rank (geometry.specimen.coordinate_domain)."""
    domain = msh.ufl_domain()
    element = domain.ufl_coordinate_element()
    sub = element.sub_elements()[0]
    if sub.variant() is None:
        marked = ufl.FiniteElement(sub.family(), sub.cell(), sub.degree(), variant="equispaced")
        set_coordinate_element(domain, ufl.VectorElement(marked, dim=element.value_size()))
    return msh


def stable_constant_order() -> None:
    """Number every later ``ufl.Constant`` (every ``fem.Constant``) from CONSTANT_COUNT_FLOOR on.

    UFL 2022 orders the operands of a sum or product of two Constants by their repr, which
    holds the Constant's global creation count as text: "10" sorts before "9". Whether the
    moduli of a form straddle a power of ten, which depends on how many Constants the process
    made before, then decides the operand order and with it the form's cache key. With counts
    of seven digits (for the next nine million Constants) text order is numeric order. Counts
    only identify Constants; nothing else depends on their values."""
    raise_constant_count(CONSTANT_COUNT_FLOOR)
