"""Ownership of PETSc objects: who made one destroys it (docs/layout.md).

petsc4py 3.18 does not free a parallel PETSc object whose last Python reference goes: it moves
it to a garbage list of the object's communicator, freed only by a collective
``PETSc.garbage_cleanup`` on that communicator. dolfinx 0.5.2 puts every vector and matrix on a
duplicate of the mesh's communicator that dies with the mesh, so an object not destroyed by
hand can never be freed; a dolfinx 0.5.2 ``Function`` never destroys the PETSc vector that
``Function.vector`` wraps around its values either (later dolfinx does, in ``Function.__del__``).

So every class here that makes PETSc objects is an :class:`Owner`: ``close()`` destroys them
(collective: call it at the same point on every rank), ``with`` closes on exit, and ``__del__``
closes as a fallback in serial only. In parallel a destroy is collective, and an owner can go
on one rank alone (an error unwinding there, or the cycle collector, whose timing differs
between ranks): a destroy then would deadlock, so there its owner must close it.
"""

from __future__ import annotations

import sys
import weakref
from collections.abc import Callable

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc


def destroy(*objs) -> None:
    """Destroy PETSc objects (None and already destroyed ones are skipped)."""
    for obj in objs:
        if obj is not None and obj.handle:
            obj.destroy()


def release_vectors(*functions: fem.Function) -> None:
    """Destroy the PETSc vectors that ``Function.vector`` wrapped around these Functions'
    values (the values stay; a later ``Function.vector`` makes a new wrapper)."""
    for f in functions:
        if f is not None and getattr(f, "_petsc_x", None) is not None:
            destroy(f._petsc_x)
            f._petsc_x = None


def dot_function(b: PETSc.Vec, w: fem.Function) -> float:
    """b·w over the owned entries, reduced over ranks; unlike ``b.dot(w.vector)`` it wraps no
    PETSc vector around w."""
    owned = b.getLocalSize()
    local = float(np.dot(b.array_r, w.x.array[:owned]))
    return b.getComm().tompi4py().allreduce(local, op=MPI.SUM)


def copy_to_function(x: PETSc.Vec, f: fem.Function) -> None:
    """f ← x (owned entries, then ghosts), without wrapping a PETSc vector around f."""
    f.x.array[: x.getLocalSize()] = x.array_r
    f.x.scatter_forward()


def weak_method(method: Callable) -> Callable:
    """A callable that calls a bound method without keeping its object alive: a PETSc callback
    made of it forms no reference cycle (SNES → callback → owner → SNES), so the owner goes by
    reference counting, at the same point on every rank."""
    ref = weakref.WeakMethod(method)

    def call(*args, **kwargs):
        return ref()(*args, **kwargs)

    return call


class Owner:
    """Base of the classes that make PETSc objects (module docstring): subclasses implement
    :meth:`_release` and give the communicator in ``comm``."""

    comm: MPI.Comm
    closed: bool = False

    def _release(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Destroy the PETSc objects made here (collective; a second call does nothing)."""
        if not self.closed:
            self.closed = True
            self._release()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            if sys.is_finalizing() or PETSc.Sys.isFinalized():
                return
            comm = getattr(self, "comm", None)
            # destroying a distributed object is collective: in parallel only close() does
            # it, since an owner can go on one rank alone (an error unwinding there)
            if comm is not None and comm.size == 1:
                self.close()
        except Exception:  # a fallback at teardown must never raise
            pass
