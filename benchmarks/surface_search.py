"""The exact closest-point search of a triangle mesh (fabricsurf/experiments/forming/surfaces/
triangulated.py) on the meshes that make it slow: a die plate about a 22 mm opening with a 2 mm
lip, as a CAD program exports it (its flat faces single slivers 21 mm long beside a finely cut
lip) and the same plate cut into well-shaped triangles (meshes.die_plate_mesh).

For each mesh it times the build (search points, k-d tree) and two sets of points: 20 000 near
the die's face (|z| < 1 mm, through ``near`` with the forming table's cutoff), as the forming
table refreshes them, and 2 000 inside the opening, at the centre of the ring of the lip and
the bore, the worst case of any exact search. ``--whole`` searches among the triangles'
centroids alone (no triangle cut), for the ratio the cutting buys. Prints a table, and the
ratios of the slivered plate's times to the well-shaped one's (docs/tool_surfaces.md).

    python3 benchmarks/surface_search.py [--lip-edge 0.5] [--around 300] [--whole]
"""

import argparse
import time

import numpy as np

from fabricsurf.experiments.forming.surfaces import closest, meshes
from fabricsurf.experiments.forming.surfaces.triangulated import TriangulatedSurface

OPENING, LIP, OUTER, THICKNESS = 22.0, 2.0, 45.0, 8.0


def slivered_plate(h: float, around: int) -> tuple[np.ndarray, np.ndarray]:
    """The plate of meshes.die_plate_mesh with its straight parts uncut: one sliver each."""
    m = max(2, int(np.ceil(0.5 * np.pi * LIP / h)))
    t = 0.5 * np.pi * np.arange(m + 1) / m
    arc = np.column_stack([OPENING + LIP - LIP * np.sin(t), LIP - LIP * np.cos(t)])
    corners = [[OPENING, THICKNESS], [OUTER, THICKNESS], [OUTER, 0.0]]
    return meshes.revolved_loop(np.vstack([arc, corners]), around)


def timed(f):
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lip-edge", type=float, default=0.5, help="lip's meridian edges (mm)")
    parser.add_argument("--around", type=int, default=300, help="segments around the axis")
    parser.add_argument("--whole", action="store_true", help="no triangle cut for the search")
    args = parser.parse_args()
    if args.whole:
        closest.PERCENTILE = 100.0
    rng = np.random.default_rng(0)
    face = np.column_stack([rng.uniform(-35, 35, (20_000, 2)), rng.uniform(-1, 1, 20_000)])
    centre = np.column_stack([rng.uniform(-15, 15, (2_000, 2)), rng.uniform(-4, 8, 2_000)])
    cutoff = 0.05 * 2 * OUTER  # the forming table's (tabulated_tools.CUTOFF sizes)
    rows = {}
    for name, mesh in [
        ("slivered", slivered_plate(args.lip_edge, args.around)),
        (
            "well-shaped",
            meshes.die_plate_mesh(OPENING, LIP, OUTER, THICKNESS, args.lip_edge, args.around),
        ),
    ]:
        surface = None

        def build(mesh=mesh):
            nonlocal surface
            surface = TriangulatedSurface(*mesh, name)

        t_build = timed(build)
        t_face = timed(lambda: surface.near(face, cutoff))
        t_centre = timed(lambda: surface.signed_distance(centre))
        rows[name] = (
            len(surface.faces),
            len(surface.points),
            surface.reach,
            t_build,
            t_face,
            t_centre,
        )
    print(
        f"{'mesh':12} {'triangles':>9} {'points':>9} {'reach mm':>8} {'build s':>8} "
        f"{'face s':>8} {'centre s':>8}",
        flush=True,
    )
    for name, (f, p, r, b, tf, tc) in rows.items():
        print(f"{name:12} {f:9d} {p:9d} {r:8.3f} {b:8.3f} {tf:8.3f} {tc:8.3f}")
    s, w = rows["slivered"], rows["well-shaped"]
    print(f"slivered / well-shaped: face {s[4] / w[4]:.2f}, centre {s[5] / w[5]:.2f}")


if __name__ == "__main__":
    main()
