"""The product boundary (docs/layout.md): a light package root, and imports inside fabricsurf/
that point one way, checked on the source with ast (function-level imports included)."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest
from mpi4py import MPI

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "fabricsurf"
HEAVY = ("dolfinx", "petsc4py", "ufl", "ffcx", "basix")

# the layers, bottom first: a module may import its own layer and the layers below it
LAYERS = [
    "errors",
    "defaults",
    "log",
    "geometry",
    "datasets",
    "model",
    "discretise",
    "experiments",
    "verification",
    "studies",
    "inverse",
    "cli",
    "fabricsurf",
]
# what a demo and its benchmark share sits on the reference solutions, but no layer of the
# library imports it: the physics, the inverse problem and the command line work without it
STUDIES_USERS = {"studies"}
# the lattice reference stands beside the layers: it imports only these, and of the layers
# only the synthetic-data generator (lattice measurements) and the reference solutions (the
# chain's and lattice's dispersion against the continua) import it
NETWORK_IMPORTS = ("network", "errors", "defaults", "log")
NETWORK_USERS = {("inverse", "synthetic"), ("verification", None)}
# within inverse: the sub-packages each may import
# (the forward model, then the uncertainty of a fit, the fit, the diagnosis; the plots draw all)
_FIT = ["contract", "forward", "uncertainty", "fitting", "diagnosis"]
INVERSE = {
    **{sub: set(_FIT[: i + 1]) for i, sub in enumerate(_FIT)},
    "plots": {*_FIT, "plots"},
    "synthetic": {"contract", "forward", "uncertainty", "fitting", "synthetic"},
    "dic": {"contract", "dic"},
}


@pytest.mark.skipif(
    MPI.COMM_WORLD.size > 1,
    reason="starts a process of its own, which cannot "
    "initialise MPI inside an mpirun rank (serial session only)",
)
def test_light_root():
    """``import fabricsurf, fabricsurf.network`` loads no FEniCSx module, nor does
    ``fabricsurf.cli.demo`` (tests/test_demos.py reads the demos' checks with it)."""
    code = (
        "import sys, fabricsurf, fabricsurf.network, fabricsurf.cli.demo\n"
        f"heavy = sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r}))\n"
        "assert not heavy, heavy\n"
        "assert fabricsurf.__version__ and 'fit' in fabricsurf.__all__\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def module_name(path: Path) -> str:
    """The installed name: geometry/ is installed as fabricsurf.geometry (pyproject.toml)."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    if parts[0] == "geometry":
        parts = ("fabricsurf", *parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def source_path(module: str) -> Path:
    """Where module ``module`` (dotted) lives in the repository, without a suffix."""
    parts = module.split(".")
    if parts[:2] == ["fabricsurf", "geometry"]:
        parts = parts[1:]
    return ROOT.joinpath(*parts)


def imported(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every absolute or relative import in ``path``, at any depth; a name
    imported from a package is taken as its submodule when it is one."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, *([base] if base else [])])
            for a in node.names:
                sub = source_path(f"{base}.{a.name}")
                sub_is_module = sub.with_suffix(".py").is_file() or sub.is_dir()
                if sub_is_module:
                    out.append((node.lineno, f"{base}.{a.name}"))
                elif base == "fabricsurf":  # a name from the package root: keep which one
                    out.append((node.lineno, f"fabricsurf:{a.name}"))
                else:
                    out.append((node.lineno, base))
    return out


def layer_of(module: str) -> tuple[str, str | None]:
    """(layer, inverse sub-package or None) of a fabricsurf module name."""
    parts = module.split(".")
    if len(parts) == 1 or parts[1] == "__main__":
        return "fabricsurf", None
    if parts[1] == "inverse":
        return "inverse", parts[2] if len(parts) > 2 else None
    return parts[1], None


def violation(source: str, target: str) -> str | None:
    """Why ``source`` (a module of fabricsurf/ or geometry/) must not import ``target``."""
    top = target.split(".")[0].split(":")[0]
    if top in ("research", "benchmarks"):
        return "research code is not part of the package"
    if source.startswith("fabricsurf.geometry"):
        return (
            None
            if top != "fabricsurf" or target.startswith("fabricsurf.geometry")
            else "the gmsh builders (geometry/) import no other part of fabricsurf"
        )
    if top != "fabricsurf":
        return None
    if target.startswith("fabricsurf:"):  # from fabricsurf import <name>
        return (
            None
            if target == "fabricsurf:__version__"
            else "the curated root is for users; inside the package import from the layer"
        )
    src, src_sub = layer_of(source)
    dst, dst_sub = layer_of(target)
    if src == "network":
        return (
            None
            if dst in NETWORK_IMPORTS
            else "network imports only network, errors, defaults and log"
        )
    if dst == "network":
        return (
            None
            if (src, src_sub) in NETWORK_USERS
            else "the physics layers do not depend on the lattice reference"
        )
    if dst == "studies" and src not in STUDIES_USERS:
        return "only the demos and benchmarks import the studies, never the library"
    if LAYERS.index(dst) > LAYERS.index(src):
        return f"layer {src} imports the higher layer {dst}"
    if src == dst == "inverse" and src_sub and dst_sub and dst_sub not in INVERSE[src_sub]:
        return f"inverse.{src_sub} imports inverse.{dst_sub}"
    return None


MODULES = sorted([*PKG.rglob("*.py"), *(ROOT / "geometry").rglob("*.py")])


def test_every_package_module_has_a_layer():
    for path in PKG.rglob("*.py"):
        layer, sub = layer_of(module_name(path))
        assert layer in LAYERS or layer == "network", path
        assert layer != "inverse" or sub is None or sub in INVERSE, path


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_one_way(path):
    source = module_name(path)
    bad = [
        f"{path.relative_to(ROOT)}:{line}: {target}: {why}"
        for line, target in imported(path)
        if (why := violation(source, target))
    ]
    assert not bad, "\n".join(bad)


def test_studies_stand_apart():
    """The studies may import the reference solutions and the plug-ins; nothing of the
    library imports them, and no module of theirs imports the inverse problem or the command
    line (the rule itself, on made-up imports)."""
    study = "fabricsurf.studies.hemisphere_forming"
    assert violation(study, "fabricsurf.verification.drapes.fishnet") is None
    assert violation(study, "fabricsurf.experiments.hemisphere") is None
    for lower in (
        "fabricsurf.verification.drapes.fishnet",
        "fabricsurf.experiments.hemisphere",
        "fabricsurf.inverse.diagnosis.report",
        "fabricsurf.cli.demo",
        "fabricsurf",
    ):
        assert violation(lower, "fabricsurf.studies.hemisphere_forming"), lower
    for higher in ("fabricsurf.inverse.diagnosis.report", "fabricsurf.cli.demo"):
        assert violation("fabricsurf.studies.woven", higher), higher


@pytest.mark.parametrize("path", sorted((ROOT / "demos").glob("demo_*.py")), ids=lambda p: p.name)
def test_demo_checks_survive_optimised_python(path):
    """A demo checks itself with ``require`` (fabricsurf/cli/demo.py), not ``assert``, which
    ``python -O`` strips: a demo run so would pass whatever its numbers."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Assert)]
    assert not lines, f"{path.name}: assert at lines {lines}; use require(condition, message)"


def import_cycles() -> list[list[str]]:
    """The strongly connected components (more than one module) of the package's import graph,
    with imports at any depth (function-level and ``TYPE_CHECKING`` ones too)."""
    names = {module_name(p) for p in MODULES}
    graph = {module_name(p): {t for _, t in imported(p) if t in names} for p in MODULES}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(v: str) -> None:  # Tarjan's algorithm
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while (w := stack.pop()) != v:
                component.append(w)
            if component:
                cycles.append(sorted([v, *component]))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_no_import_circle():
    """No two modules import each other, directly or round a longer loop: a circle makes the
    import order matter and hides which module a piece of knowledge belongs to."""
    assert import_cycles() == []


def test_installed_packages_listed():
    """Every package folder of the product is in pyproject.toml's ``packages`` (an explicit list,
    as geometry/ is installed as fabricsurf.geometry): a new sub-package cannot be left out of
    an installation, and nothing else is installed."""
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {
        module_name(p)
        for p in [*PKG.rglob("__init__.py"), *(ROOT / "geometry").rglob("__init__.py")]
    }
    assert sorted(config["packages"]) == sorted(folders)
    assert config["package-dir"] == {"fabricsurf.geometry": "geometry"}


# -- messages: one channel (fabricsurf/log.py) ----------------------------------------------
LOGGING_SET_UP = {"fabricsurf/log.py", "fabricsurf/cli/__init__.py"}
"""Where a handler or a level may be set and the flags -v/-q become levels: log.configure, and
the command line's quieting of the JIT compiler's loggers (compiler_messages)."""
SET_UP_CALLS = {"basicConfig", "addHandler", "setLevel", "captureWarnings", "disable"}


def message_faults(path: Path) -> list[str]:
    """What in a module of the package bypasses the logger (fabricsurf/log.py): ``print``,
    ``warnings.warn``, a logging set-up outside :data:`LOGGING_SET_UP`, a ``propagate``
    assignment, a public function with a ``verbose`` parameter."""
    rel = str(path.relative_to(ROOT))
    bad = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), rel)):
        if isinstance(node, ast.Call):
            f = node.func
            name = (
                f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
            )
            owner = (
                f.value.id if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) else ""
            )
            if name == "print" and isinstance(f, ast.Name):
                bad.append(f"{rel}:{node.lineno}: print (log.rank0 instead)")
            elif owner == "warnings" and name.startswith("warn"):
                bad.append(f"{rel}:{node.lineno}: warnings.{name} (log.warn instead)")
            elif name in SET_UP_CALLS and rel not in LOGGING_SET_UP:
                bad.append(f"{rel}:{node.lineno}: {name}: the library configures no logging")
        elif (
            isinstance(node, ast.Assign)
            and rel not in LOGGING_SET_UP
            and any(isinstance(t, ast.Attribute) and t.attr == "propagate" for t in node.targets)
        ):
            bad.append(f"{rel}:{node.lineno}: propagate: the package's messages propagate")
        elif (
            isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and not node.name.startswith("_")
            and rel not in LOGGING_SET_UP
        ):
            args = [a.arg for a in (*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs)]
            if "verbose" in args:
                bad.append(
                    f"{rel}:{node.lineno}: {node.name}(verbose=...): use the levels "
                    "(progress at log.PROGRESS, detail at DEBUG)"
                )
    return sorted(bad, key=lambda b: int(b.split(":")[1]))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_messages_go_through_the_logger(path):
    """The package reports through its module loggers only (fabricsurf/log.py): no print, no
    warnings.warn, no logging set-up at import or anywhere but log.configure, no verbose
    flags."""
    bad = message_faults(path)
    assert not bad, "\n".join(bad)


def test_message_rule_catches_a_print(tmp_path, monkeypatch):
    """The rule itself, on a made-up module."""
    module = ROOT / "fabricsurf" / "_made_up.py"
    monkeypatch.setattr(
        Path,
        "read_text",
        lambda self, encoding=None: (
            "import logging, warnings\n"
            "def f(x, verbose=False):\n    print(x)\n    warnings.warn('w')\n"
            "logging.getLogger('fabricsurf').addHandler(logging.StreamHandler())\n"
        ),
    )
    bad = message_faults(module)
    assert [b.split(":")[2].split()[0] for b in bad] == [
        "f(verbose=...)",
        "print",
        "warnings.warn",
        "addHandler",
    ], bad


MAX_LINES = 300
"""A module longer than this holds more than one concern (style guide)."""
MAX_MODULES = 12
"""A folder with more modules than this is a flat bag: it wants sub-packages."""


def test_modules_and_folders_stay_small():
    """No module of the package (or of geometry/) over MAX_LINES lines, no folder over
    MAX_MODULES modules (``__init__.py`` not counted)."""
    long = [
        f"{p.relative_to(ROOT)}: {n} lines"
        for p in MODULES
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    ]
    folders = {p.parent for p in MODULES}
    bags = [
        f"{d.relative_to(ROOT)}: {n} modules"
        for d in sorted(folders)
        if (n := len([p for p in d.glob("*.py") if p.name != "__init__.py"])) > MAX_MODULES
    ]
    assert long == [] and bags == []
