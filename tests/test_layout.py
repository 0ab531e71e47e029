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
LAYERS = ["errors", "constants", "log", "datasets", "model", "discretise", "experiments",
          "verification", "studies", "inverse", "cli", "fabricsurf"]
# what a demo and its benchmark share sits on the reference solutions, but no layer of the
# library imports it: the physics, the inverse problem and the command line work without it
STUDIES_USERS = {"studies"}
# the lattice reference stands beside the layers: it imports only these, and of the layers
# only the synthetic-data generator (lattice measurements) and the reference solutions (the
# chain's and lattice's dispersion against the continua) import it
NETWORK_IMPORTS = ("network", "errors", "constants", "log")
NETWORK_USERS = {("inverse", "synthetic"), ("verification", None)}
# within inverse: the sub-packages each may import
INVERSE = {
    "contract": {"contract"},
    "fitting": {"contract", "fitting"},
    "plots": {"contract", "fitting", "plots"},
    "synthetic": {"contract", "fitting", "synthetic"},
    "dic": {"contract", "dic"},
}


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="starts a process of its own, which cannot "
                    "initialise MPI inside an mpirun rank (serial session only)")
def test_light_root():
    """``import fabricsurf, fabricsurf.network`` loads no FEniCSx module, nor does
    ``fabricsurf.cli.demo`` (tests/test_demos.py reads the demos' checks with it)."""
    code = ("import sys, fabricsurf, fabricsurf.network, fabricsurf.cli.demo\n"
            f"heavy = sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r}))\n"
            "assert not heavy, heavy\n"
            "assert fabricsurf.__version__ and 'fit' in fabricsurf.__all__\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


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
                sub = ROOT.joinpath(*f"{base}.{a.name}".split("."))
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
    if source.startswith("geometry"):
        return "geometry imports no fabricsurf" if top == "fabricsurf" else None
    if top != "fabricsurf":
        return None
    if target.startswith("fabricsurf:"):  # from fabricsurf import <name>
        return None if target == "fabricsurf:__version__" else \
            "the curated root is for users; inside the package import from the layer"
    src, src_sub = layer_of(source)
    dst, dst_sub = layer_of(target)
    if src == "network":
        return None if dst in NETWORK_IMPORTS else \
            "network imports only network, errors and constants"
    if dst == "network":
        return None if (src, src_sub) in NETWORK_USERS else \
            "the physics layers do not depend on the lattice reference"
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
    bad = [f"{path.relative_to(ROOT)}:{line}: {target}: {why}"
           for line, target in imported(path) if (why := violation(source, target))]
    assert not bad, "\n".join(bad)


def test_studies_stand_apart():
    """The studies may import the reference solutions and the plug-ins; nothing of the
    library imports them, and no module of theirs imports the inverse problem or the command
    line (the rule itself, on made-up imports)."""
    assert violation("fabricsurf.studies.forming", "fabricsurf.verification.fishnet") is None
    assert violation("fabricsurf.studies.forming", "fabricsurf.experiments.hemisphere") is None
    for lower in ("fabricsurf.verification.fishnet", "fabricsurf.experiments.hemisphere",
                  "fabricsurf.inverse.fitting.report", "fabricsurf.cli.demo", "fabricsurf"):
        assert violation(lower, "fabricsurf.studies.forming"), lower
    for higher in ("fabricsurf.inverse.fitting.report", "fabricsurf.cli.demo"):
        assert violation("fabricsurf.studies.woven", higher), higher


@pytest.mark.parametrize("path", sorted((ROOT / "demos").glob("demo_*.py")), ids=lambda p: p.name)
def test_demo_checks_survive_optimised_python(path):
    """A demo checks itself with ``require`` (fabricsurf/cli/demo.py), not ``assert``, which
    ``python -O`` strips: a demo run so would pass whatever its numbers."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Assert)]
    assert not lines, f"{path.name}: assert at lines {lines}; use require(condition, message)"
