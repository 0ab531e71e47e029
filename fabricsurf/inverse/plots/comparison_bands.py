"""The prediction bands of a comparison at a saved fit's moduli, as files: the force curve's
band (``{prefix}force_band.csv`` and ``.png``) and the field's at the measurement points
(``{prefix}field_band.csv``, and a map of the last step in ``.png``) of every experiment, with
the prefixes of :func:`~fabricsurf.inverse.plots.outputs.write_comparison`. The bands are
:func:`~fabricsurf.inverse.fitting.compare.compare`'s (``Comparison.bands``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import on_rank0
from fabricsurf.experiments import get_test
from fabricsurf.inverse.fitting.band import write_band
from fabricsurf.inverse.plots import figures, outputs


def write_band_files(out: Path, exps: list, bands: dict, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """The files of ``bands`` ({experiment name: band}, :func:`~.band.force_band`) of the
    experiments ``exps`` into ``out`` (module docstring); rank 0 writes, every rank calls."""
    for exp in exps:
        band = bands[exp.name]
        pre = "" if len(exps) == 1 else f"{outputs.slug(exp.name)}_"
        if band["force"] is not None:
            on_rank0(comm, write_band, out / f"{pre}force_band.csv", band, "load")
            on_rank0(
                comm,
                figures.force_band,
                band,
                out / f"{pre}force_band.png",
                f"{exp.name}: prediction at the saved fit",
                (exp.path, exp.force),
                xlabel=get_test(exp.test).path_label,
            )
        field = band["field_half_width"]
        if field is not None:
            field = np.asarray(field, float)
            on_rank0(comm, outputs.field_band_csv, out / f"{pre}field_band.csv", exp, field)
            on_rank0(comm, figures.field_band, exp, field, out / f"{pre}field_band.png")
