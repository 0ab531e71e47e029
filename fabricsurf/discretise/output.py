"""Output: XDMF time series of u and derived fields, step logs (CSV/JSON). Messages go through
the ``fabricsurf`` logger (:mod:`fabricsurf.log`)."""

from __future__ import annotations

import csv
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem, io
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabricsurf.discretise.resources import Owner, destroy
from fabricsurf.errors import InputError
from fabricsurf.model.kinematics import Kinematics


def derived_fields(kin: Kinematics) -> dict:
    """Named scalar fields for ParaView: λ, μ, γ, J and, in 3D, K_L, K_M, T."""
    fields = {"lambda": kin.lam, "mu": kin.mu, "gamma": kin.gamma, "J": kin.J}
    if kin.d == 3 and kin.H is not None:
        fields.update({"K_L": kin.K_L, "K_M": kin.K_M, "T": kin.T})
    return fields


class FieldWriter(Owner):
    """Writes u and the derived fields on P1 to ``path`` (XDMF + h5), one time per call.

    Derived fields are lumped L2 projections onto P1, f_i = ∫ f φ_i / ∫ φ_i, computed with one
    compiled form for all fields (XDMF in dolfinx 0.5.2 holds P1 data only). ``extra`` adds
    named UFL fields (e.g. the fibre tensions); ``qdeg`` must equal the degree of any
    quadrature-space coefficient in them (the multipliers of exact constraints). :meth:`close`
    closes the file and destroys the two work vectors.
    """

    def __init__(
        self, path: Path, u: fem.Function, kin: Kinematics, qdeg: int = 2, extra: dict | None = None
    ) -> None:
        msh = u.function_space.mesh
        self.comm, self.u = msh.comm, u
        d = u.function_space.dofmap.index_map_bs
        self.V1 = fem.VectorFunctionSpace(msh, ("CG", 1), dim=d)
        self.u1 = fem.Function(self.V1, name="u")
        exprs = {**derived_fields(kin), **dict(extra or {})}
        self.names = list(exprs)
        k = len(self.names)
        self.Vk = fem.VectorFunctionSpace(msh, ("CG", 1), dim=k)
        self.S1 = fem.FunctionSpace(msh, ("CG", 1))
        self.scalars = [fem.Function(self.S1, name=n) for n in self.names]
        v = ufl.TestFunction(self.Vk)
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": qdeg})
        self.rhs = fem.form(ufl.inner(ufl.as_vector(list(exprs.values())), v) * dx)
        lumped = fem_petsc.assemble_vector(fem.form(ufl.inner(ufl.as_vector([1.0] * k), v) * dx))
        lumped.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.lumped, self.b = lumped, lumped.duplicate()
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        self.file = io.XDMFFile(self.comm, str(path), "w")
        self.file.write_mesh(msh)

    def project(self) -> None:
        b = self.b
        with b.localForm() as b_local:
            b_local.set(0.0)
        fem_petsc.assemble_vector(b, self.rhs)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        b.pointwiseDivide(b, self.lumped)
        b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with b.localForm() as b_local:
            arr = b_local.array_r.reshape(-1, len(self.names))
            for i, f in enumerate(self.scalars):
                f.x.array[:] = arr[:, i]

    def write(self, t: float) -> None:
        self.u1.interpolate(self.u)
        self.project()
        self.file.write_function(self.u1, t)
        for f in self.scalars:
            self.file.write_function(f, t)

    def _release(self) -> None:
        self.file.close()
        destroy(self.lumped, self.b)


class StepLog:
    """Rows of per-step scalars (already reduced over ranks), saved as CSV and JSON on rank 0."""

    def __init__(self, comm: MPI.Comm, out: Path, stem: str = "steps") -> None:
        self.comm, self.out, self.stem = comm, Path(out), stem
        self.rows: list[dict] = []

    def add(self, **row) -> None:
        self.rows.append(
            {k: (float(v) if isinstance(v, (np.floating, float)) else v) for k, v in row.items()}
        )
        self.save()

    def save(self) -> None:
        """Write the rows (rank 0; a failure there is raised on every rank)."""
        if self.rows:
            on_rank0(self.comm, self._save)

    def _save(self) -> None:
        """Each file written whole, then renamed over the last (an interrupt leaves the
        previous step's complete file)."""
        self.out.mkdir(parents=True, exist_ok=True)
        tmp = self.out / f"{self.stem}.csv.tmp"
        with open(tmp, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(self.rows[0]))
            w.writeheader()
            w.writerows(self.rows)
        tmp.replace(self.out / f"{self.stem}.csv")
        _write_json_file(self.out / f"{self.stem}.json", self.rows)


def on_rank0(comm: MPI.Comm, fn: Callable, *args, **kwargs):
    """Run ``fn`` on rank 0 only; an exception there is raised on every rank (an InputError as
    itself, anything else as OSError naming it), so no rank waits forever in the next
    collective call. Returns fn's result on rank 0 (None elsewhere)."""
    result, error = None, None
    if comm.rank == 0:
        try:
            result = fn(*args, **kwargs)
        except InputError as e:
            error = (True, str(e))
        except Exception as e:  # re-raised below on every rank
            error = (False, f"{type(e).__name__}: {e}")
    error = comm.bcast(error, root=0)
    if error is not None:
        raise InputError(error[1]) if error[0] else OSError(error[1])
    return result


def _write_json_file(path: Path, data: dict | list) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    tmp.replace(path)


def write_json(comm: MPI.Comm, path: Path, data: dict) -> None:
    """Write JSON on rank 0, atomically (a temporary file, then rename); collective-safe."""
    on_rank0(comm, _write_json_file, Path(path), data)
