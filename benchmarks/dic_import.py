"""Size and speed of ``import-dic`` (docs/dic.md, "Size and speed"): a synthetic DICe export of
a 187 × 119 mm bias specimen (pixels, 2° tilt, 3 % holes, σ = 0.01 mm) at a chosen point
spacing, imported in a fresh process per case, printing the wall time, the peak RSS and the
noise estimate.

    .venv/bin/python benchmarks/dic_import.py [--spacing 0.2] [--out /tmp/dic_bench]

Cases: one image binned to 2 mm, two images binned, two images not binned. The RSS is the
importing process's peak (``ru_maxrss``), the Python, numpy and fabricsurf baseline included
(printed as "before")."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from fabricsurf.inverse.dic.export import spec_text, write_images
from fabricsurf.inverse.dic.frame import Frame
from fabricsurf.inverse.dic.layouts import LAYOUTS

L, W = 187.0, 119.0
CAMERA = Frame(0.05, True, (150.0, 2500.0), "left", 2.0)
RUN = """
import json, resource, sys, time
from fabricsurf.inverse.dic.description.spec import read_spec
from fabricsurf.inverse.dic.importer import import_dic
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
t0 = time.perf_counter()
exp, rep = import_dic(read_spec(sys.argv[1]))
print(json.dumps({"points": rep["points_read"], "rows": len(exp.X), "seconds":
                  time.perf_counter() - t0, "before_mb": before, "peak_mb":
                  resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "noise_std": exp.noise_std}))
"""


def spec(images: list[int], pitch: float | None) -> str:
    files = f"img/DICe_solution_{'*' if len(images) > 1 else '01'}.txt"
    return spec_text(
        CAMERA,
        name="bench",
        layout="dice",
        files=files,
        length=L,
        width=W,
        images=images,
        path=[5.0 * k for k in images],
        pitch=pitch,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spacing", type=float, default=0.2, help="DIC point spacing (mm)")
    ap.add_argument("--out", type=Path, default=Path("/tmp/dic_bench"))
    args = ap.parse_args()
    xs, ys = np.arange(1, L - 1, args.spacing), np.arange(1, W - 1, args.spacing)
    X = np.array(np.meshgrid(xs, ys, indexing="ij")).reshape(2, -1).T
    rng = np.random.default_rng(0)
    U = [
        np.column_stack([t * X[:, 0] / L, 0.001 * t * (X[:, 1] - W / 2)])
        + rng.normal(0, 0.01, X.shape)
        for t in (5.0, 10.0)
    ]
    write_images(args.out / "img", LAYOUTS["dice"], CAMERA, [1, 2], X, U, holes=0.03)
    print(f"{len(X)} points an image ({args.spacing} mm spacing)")
    for name, images, pitch in (
        ("1 image, 2 mm bins", [1], 2.0),
        ("2 images, 2 mm bins", [1, 2], 2.0),
        ("2 images, no binning", [1, 2], None),
    ):
        toml = args.out / (name.replace(" ", "_").replace(",", "") + ".toml")
        toml.write_text(spec(images, pitch))
        r = subprocess.run([sys.executable, "-c", RUN, str(toml)], capture_output=True, text=True)
        if r.returncode:
            raise SystemExit(f"{name}: {r.stderr}")
        m = json.loads(r.stdout)
        print(
            f"{name:22s} {m['points']:9d} points → {m['rows']:8d} rows  {m['seconds']:6.2f} s"
            f"  peak RSS {m['peak_mb']:5.0f} MB (before {m['before_mb']:.0f} MB)  noise_std "
            f"{m['noise_std']:.4g} mm"
        )


if __name__ == "__main__":
    main()
