"""A tool file at a CAD export's size: time and memory of reading, checking and searching a
binary STL against its number of triangles (docs/tool_surfaces.md, "At a CAD file's size").

For each level an icosphere of radius 40 mm (20·4^level triangles) is written as a binary STL
and read by ``files.read_surface`` (weld, topology checks, normals, search points, k-d tree);
then 10⁵ points within 2 mm of the sphere go through ``near`` (cutoff 0.5 mm: the contact
table's query) and 2·10⁴ within 3 mm through ``signed_distance`` (the drape's, exact at any
distance). Prints per level the seconds of each, the bytes per triangle of the surface's
arrays (the k-d tree's own not counted) and of each stage's peak (tracemalloc: numpy's
arrays), and the read time per triangle over the first level's (1 = linear in the triangles).

    python3 benchmarks/surface_size.py [--levels 6,7,8]
"""

import argparse
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from fabricsurf.experiments.forming.surfaces import files, meshes

R = 40.0


def points_about(n: int, spread: float, seed: int) -> np.ndarray:
    """n random points whose distance from the centre is R ± spread."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    return x * (R + rng.uniform(-spread, spread, n))[:, None] / np.linalg.norm(x, axis=1)[:, None]


def measured(f):
    """(result, seconds, peak bytes of numpy's arrays above the start) of f()."""
    tracemalloc.start()
    t = time.perf_counter()
    out = f()
    seconds = time.perf_counter() - t
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return out, seconds, peak


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", default="6,7,8", help="icosphere subdivisions")
    args = parser.parse_args()
    near, far = points_about(100_000, 2.0, 1), points_about(20_000, 3.0, 2)
    print(
        f"{'triangles':>10} {'read s':>7} {'near s':>7} {'exact s':>7} {'kept B/tri':>10} "
        f"{'peak read':>9} {'peak near':>9} {'peak exact':>10}",
        flush=True,
    )
    first = None
    for level in (int(v) for v in args.levels.split(",")):
        v, f = meshes.icosphere(R, level)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "sphere.stl"
            files.write_stl(path, v, f)
            surface, t_read, p_read = measured(lambda p=path: files.read_surface(p, "mm"))
        _, t_near, p_near = measured(lambda s=surface: s.near(near, 0.5))
        _, t_exact, p_exact = measured(lambda s=surface: s.signed_distance(far))
        kept = sum(a.nbytes for a in vars(surface).values() if isinstance(a, np.ndarray))
        n = len(f)
        print(
            f"{n:10d} {t_read:7.2f} {t_near:7.2f} {t_exact:7.2f} {kept / n:10.0f} "
            f"{p_read / n:9.0f} {p_near / n:9.0f} {p_exact / n:10.0f}",
            flush=True,
        )
        first = first or (n, t_read)
        ratio = t_read / n / (first[1] / first[0])
        print(f"{'':10} read time per triangle / the first level's: {ratio:.2f}", flush=True)


if __name__ == "__main__":
    main()
