"""The two kinematic drapes of a hemisphere against each other over the whole cap, and each
against the Chebyshev net of Hazzidakis' equation on the diagonal, as the cell size falls
(docs/forming.md, "Two drapes"): numpy only, serial.

    python benchmarks/drape.py [--R 20] [--angles 45 -45] [--polar 90]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from fabricsurf.verification.drapes import drape_map, fishnet, goursat_drape


def chebyshev(R: float, u: float, theta0: float) -> float:
    """γ(u, u) of the Chebyshev net, Richardson-extrapolated from the box scheme at 120 and 240
    steps (second order)."""
    return (
        4 * fishnet.chebyshev_shear(R, u, u, 240, theta0)
        - fishnet.chebyshev_shear(R, u, u, 120, theta0)
    ) / 3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--R", type=float, default=20.0)
    ap.add_argument("--angles", type=float, nargs=2, default=(45.0, -45.0))
    ap.add_argument("--polar", type=float, default=90.0, help="cap's polar angle (deg)")
    args = ap.parse_args()
    R, angles = args.R, tuple(args.angles)
    pts = drape_map.cap_grid(R, angles, R / 20.0, args.polar)
    theta0 = math.acos(float(fishnet.unit(angles[0]) @ fishnet.unit(angles[1])))
    u = 0.6 * R
    ref = chebyshev(R, u, theta0)
    print(
        f"R = {R:g} mm, fibres {angles}, {len(pts)} points within {args.polar:g}° of the pole;"
        f" Chebyshev net at u = v = 0.6 R: {math.degrees(ref):.6f}°"
    )
    print(
        "| a | max of fishnet − Goursat (deg) | RMS of it (deg) | fishnet − Chebyshev at "
        "u = v = 0.6 R (deg) | Goursat − Chebyshev (deg) | s |"
    )
    print("|---|---|---|---|---|---|")
    for k in (10, 20, 40, 80):
        a = R / k
        t0 = time.perf_counter()
        agree = drape_map.drape_agreement(R, a, angles, pts)
        m = round(u / a)
        fish = fishnet.drape(R, a, m + 1, angles)
        g_f = fishnet.node_shear(fish)[2 * m, 2 * m]
        net = goursat_drape.hemisphere(R, angles, a, u + a)
        g_g = net.shear[net.n + m, net.n + m]
        print(
            f"| R/{k} | {agree['max_deg']:.3g} | {agree['rms_deg']:.3g} | "
            f"{math.degrees(g_f - ref):.3g} | {math.degrees(g_g - ref):.3g} | "
            f"{time.perf_counter() - t0:.1f} |"
        )
    largest = np.abs(drape_map.drapes_at(R, pts, angles)["fishnet_deg"]).max()
    print(f"largest shear on the cap {largest:.2f}°")


if __name__ == "__main__":
    main()
