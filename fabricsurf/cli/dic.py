"""``fabricsurf import-dic DIC.toml --out DIR``: DIC exports (one CSV per image) → a
measurement directory of the contract (experiment.toml, field.csv[, force.csv]) plus
dic_import.json (what was read, dropped, binned, and the noise level with how it was found).

DIC.toml describes the files, their layout, the camera frame and the image-to-step mapping
(docs/dic.md). The work runs on rank 0; an error there ends every rank with its message, and
nothing is written to DIR unless the whole import succeeds (cli.outdir).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from mpi4py import MPI

from fabricsurf import __version__
from fabricsurf.cli.outdir import OutputDir
from fabricsurf.discretise.output import on_rank0, write_json
from fabricsurf.log import rank0

log = logging.getLogger(__name__)

COMM = MPI.COMM_WORLD
OUTPUTS = ("experiment.toml", "field.csv", "force.csv", "dic_import.json")


def add_parser(sub, formatter) -> None:
    p = sub.add_parser(
        "import-dic",
        formatter_class=formatter,
        help="DIC exports (CSV per image) → a measurement directory",
    )
    p.add_argument(
        "spec",
        type=Path,
        help="the import description, e.g. dic.toml "
        "(docs/dic.md: files, layout, units, frame, steps, binning)",
    )
    p.add_argument(
        "--out",
        required=True,
        type=Path,
        help="the measurement directory to write (experiment.toml, field.csv, "
        "force.csv, dic_import.json)",
    )
    p.set_defaults(func=run)


def write_directory(stage: Path, exp, report: dict) -> None:
    """The contract files of ``exp`` (mm, N; the contract's own writer, full precision) and the
    report, into ``stage`` (one rank)."""
    from fabricsurf.inverse.contract.writer import write_files

    write_files(stage, exp)
    write_json(MPI.COMM_SELF, stage / "dic_import.json", report)


def _reads_back(stage: Path) -> None:
    """The written directory must pass the loader's own checks, or nothing is published."""
    from fabricsurf.errors import DataError
    from fabricsurf.inverse.contract.data import load_experiment

    try:
        load_experiment(stage)
    except DataError as e:
        raise DataError(
            f"the imported data fail the measurement contract's checks, so nothing is written: {e}"
        ) from None


def _import(spec_path: Path, stage: Path) -> str:
    from fabricsurf.inverse.dic.description.spec import read_spec
    from fabricsurf.inverse.dic.importer import import_dic

    spec = read_spec(spec_path)
    exp, report = import_dic(spec)
    report["provenance"] = {
        "fabricsurf": __version__,
        "spec": str(spec_path.resolve()),
        "export_directory": str(spec.root.resolve()),
    }
    write_directory(stage, exp, report)
    _reads_back(stage)
    noise = report["noise"]
    notes = [
        f"note: {role} column dropped ({why})" for role, why in report["dropped_columns"].items()
    ]
    if report["coordinates"]["converted"]:
        notes.append(
            "note: the export's coordinates are deformed positions; reference = "
            "deformed − displacement"
        )
    return (
        f"{report['points_read']} points read from {len(report['files'])} images "
        f"({report['layout']}, {', '.join(report['encoding'])}), {report['holes']} holes "
        f"and {report['outside_dropped']} points off the specimen dropped; "
        f"{report['rows_written']} field rows written"
        + (f" (binned to {spec.pitch:g} mm)" if spec.pitch else "")
        + "; noise_std "
        + ("" if noise["noise_std"] is None else f"{noise['noise_std']:.3g} mm ")
        + f"({noise['method']})"
        + "".join("\n" + n for n in notes)
    )


def _inputs(spec_path: Path) -> tuple[tuple[str, Path], ...]:
    """The spec and the export files it matches (--out must keep apart from them)."""
    import tomllib

    from fabricsurf.inverse.dic.files import matching

    found: list[tuple[str, Path]] = [(f"import description {spec_path}", spec_path)]
    try:
        pattern = tomllib.loads(spec_path.read_text())["export"]["files"]
        found += [(f"export file {p}", p) for p in matching(spec_path.parent, str(pattern))]
    except (OSError, KeyError, TypeError, ValueError):
        pass  # read_spec names the problem
    return tuple(found)


def run(args: argparse.Namespace) -> int:
    od = OutputDir(args.out, COMM, files=OUTPUTS, inputs=_inputs(args.spec))
    with od as stage:
        message = on_rank0(COMM, _import, args.spec, stage)
    rank0(log, COMM, f"{message}\nmeasurement directory: {args.out}")
    return 0
