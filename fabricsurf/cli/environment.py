"""The process's environment, checked by the command line before any computation (docs/usage.md,
"Environment"): what would otherwise fail deep inside a run, with a traceback naming neither the
variable nor the remedy.

* ``FABRICSURF_LOCAL_CELLS`` (:func:`fabricsurf.inverse.forward.ranks.local_cells`): read when
  the first forward model is built, by rank 0 alone; a bad value ended a 2-rank ``compare``
  with a ValueError traceback and MPI_ABORT, and was ignored by a serial run.
* The JIT compiler's files, under ``HOME`` unless ``XDG_CONFIG_HOME`` / ``XDG_CACHE_HOME`` say
  otherwise: FFCx and DOLFINx read their settings from ``~/.config/ffcx/ffcx_parameters.json``
  and ``~/.config/dolfinx/dolfinx_jit_parameters.json`` (and the same names in the working
  directory), and keep compiled forms in ``~/.cache/fenics``. A ``HOME`` that lies under a file
  ended the first compilation with "Not a directory: …/ffcx_parameters.json".

Each rank checks its own environment (``mpirun -x`` can give the ranks different ones); the
first problem found on any rank is raised on every rank, so all end with status 2.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from mpi4py import MPI

from fabricsurf.errors import InputError

COMPILING = ("bias", "compare", "fit", "diagnose")
"""The commands that solve (and so compile forms); ``terms`` and ``import-dic`` do not."""


def check_environment(comm: MPI.Comm, command: str) -> None:
    """Raise the first problem of any rank's environment, on every rank, for a ``command`` that
    solves; nothing for the others."""
    problem = None
    if command in COMPILING:
        try:
            local_cells()
            jit_files()
        except InputError as e:
            problem = str(e)
    found = [p for p in comm.allgather(problem) if p is not None]
    if found:
        raise InputError(found[0])


def local_cells() -> None:
    from fabricsurf.inverse.forward.ranks import local_cells as threshold

    threshold()


def _variable(name: str) -> str:
    """``NAME=value`` of the variable a path derives from: ``name`` when it is set, else HOME."""
    if os.environ.get(name) is not None:
        return f"{name}={os.environ[name]}"
    return f"HOME={os.environ.get('HOME', '(not set: ' + str(_home()) + ')')}"


def _home() -> Path:
    try:
        return Path.home()
    except RuntimeError:  # no HOME and no entry in the password database
        return Path("~")


def _why(path: Path) -> str:
    """Why ``path`` (a directory, or a file in it) cannot be made: the part of it that is a
    file, or the nearest existing directory that is not writable; "" if nothing stops it."""
    probe = path
    while not os.path.lexists(probe) and probe != probe.parent:
        probe = probe.parent
    if probe == path and probe.is_dir():
        return ""
    if not probe.is_dir():
        return f"{probe} is a file, not a directory"
    if not os.access(probe, os.W_OK | os.X_OK):
        return f"{probe} is not writable"
    return ""


def _settings(files: list[tuple[Path, str | None]], problems: list) -> dict:
    """The JIT settings files that exist, read as FFCx and DOLFINx read them (``files``: path
    and the variable its directory comes from, None for the working directory); DOLFINx's
    merged. One that cannot be read is added to ``problems``; one in the working directory
    that cannot be read, or any that is not a JSON object, is an InputError naming it."""
    merged: dict = {}
    for path, source in files:
        try:
            text = path.read_text()
        except FileNotFoundError:
            continue
        except OSError as e:
            if source is None:
                raise InputError(
                    f"{path}: the JIT compiler's settings file cannot be read "
                    f"({e.strerror}); remove it, or run elsewhere"
                ) from None
            if not problems:  # the first of them says it
                problems.append(
                    (source, f"read its settings file {path}", _why(path.parent) or e.strerror)
                )
            continue
        try:
            value = json.loads(text)
            why = (
                ""
                if isinstance(value, dict)
                else f"holds a {type(value).__name__}, not a JSON object"
            )
        except ValueError as e:
            value, why = None, f"is not valid JSON ({e})"
        if why:
            raise InputError(
                f"{path}: the JIT compiler's settings file {why}; correct it or remove it"
            )
        if path.name.startswith("dolfinx"):
            merged |= value
    return merged


def jit_files() -> None:
    """The JIT compiler's settings files readable and its cache directory possible to create
    (module docstring); an InputError names the variable, the paths and the remedy."""
    config_source = _variable("XDG_CONFIG_HOME")
    config = Path(os.getenv("XDG_CONFIG_HOME", default=_home() / ".config"))
    cache_source = _variable("XDG_CACHE_HOME")
    cache = Path(os.getenv("XDG_CACHE_HOME", default=_home() / ".cache")) / "fenics"
    problems: list[tuple[str, str, str]] = []
    settings = _settings(
        [
            (config / "ffcx" / "ffcx_parameters.json", config_source),
            (Path.cwd() / "ffcx_parameters.json", None),
            (config / "dolfinx" / "dolfinx_jit_parameters.json", config_source),
            (Path.cwd() / "dolfinx_jit_parameters.json", None),
        ],
        problems,
    )
    if "cache_dir" in settings:
        cache = Path(str(settings["cache_dir"])).expanduser()
        cache_source = "cache_dir in dolfinx_jit_parameters.json"
    why = _why(cache)
    if why:
        problems.insert(0, (cache_source, f"create its cache of compiled forms {cache}", why))
    if problems:
        sources = list(dict.fromkeys(src for src, _, _ in problems))
        names = list(dict.fromkeys(src.split("=")[0] for src in sources))
        remedy = f"set {' and '.join(names)} to a directory you can write to"
        if names == ["HOME"]:
            remedy += " (or XDG_CACHE_HOME and XDG_CONFIG_HOME)"
        whys = {why for _, _, why in problems}
        if len(whys) == 1 and len(problems) == 2:  # one cause (HOME under a file): said once
            text = (
                f"{whys.pop()}, so the JIT compiler can neither {problems[0][1]} nor "
                f"{problems[1][1]}"
            )
        else:
            text = "the JIT compiler cannot " + " nor ".join(
                f"{what} ({why})" for _, what, why in problems
            )
        raise InputError(f"{'; '.join(sources)}: {text}; {remedy}")
