"""Form cache keys that depend on the form only.

FFCx caches a compiled form under its UFL signature. Two behaviours of the pinned FFCx 0.5 and
UFL 2022 make the signature of one and the same form depend on what the process did before, so
that identical kernels were compiled again (once per key; the large second-gradient kernels
take minutes each). Both are neutralised here, before any of our forms is built; the tests are
in tests/test_jit_keys.py. So is the wait for a kernel that another process is compiling
(:func:`wait_for_other_compiles`).
"""

import ufl
from dolfinx import mesh as dmesh

from fabricsurf.discretise.compat import (
    raise_constant_count,
    raise_jit_wait,
    set_coordinate_element,
)

CONSTANT_COUNT_FLOOR = 10**6

JIT_WAIT = 900
"""Seconds a process waits for a kernel that another process is compiling into the same cache
before giving up (dolfinx's default is 10). Two jobs started together on a cold cache (two
diagnoses of a user, the test suite's two processes) compile the same forms, and whichever
comes second waits: the large second-gradient kernels take minutes, so with 10 s it failed
with a TimeoutError instead of loading the kernel the first finished. A kernel whose compiler
was killed leaves its C file without the mark of completion; a later run then waits this long
and fails with FFCx's message naming the file to remove."""


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


def wait_for_other_compiles() -> None:
    """Wait up to :data:`JIT_WAIT` s for a kernel another process is compiling (the default of
    every later form; a user's dolfinx_jit_parameters.json still decides)."""
    raise_jit_wait(JIT_WAIT)
