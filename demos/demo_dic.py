# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # DIC exports as they are written: import → diagnose
#
# Run with `mpirun -n 2 python demos/demo_dic.py --out out/dic` (about 20 s on 2 ranks with the
# forms compiled). `--quick`, the option every demo has (the test suite passes it), runs this
# same demo with the same checks: it is quick as it is.
#
# A DIC system does not write our measurement contract: it writes one file per image, in the
# camera's frame (pixels, y pointing down, the specimen a little tilted), with holes where
# facets were lost, and a few hundred thousand points. This demo makes such an export of a
# synthetic bias-extension test whose truth is known, reads it back with
# `fabricsurf import-dic` (binning, frame, holes, noise estimate), checks that the imported
# field is the truth to within its noise (a bias test of the import), and asks
# `fabricsurf diagnose` which effect the baseline model `fibre_stretch + shear` is missing.
#
# The truth: a 70 × 35 mm specimen, ±45° fibres, k_l = k_m = 30 N/mm, k_s = 0.5 N/mm and
# in-plane fibre bending A_g = 15 N·mm (the hidden effect), grip displacements 1.2, 2.4 and
# 3.6 mm, solved on a mesh of h = 2.2 mm (the diagnosis then uses its own mesh).

# %%
import json
import logging
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.cli import main as cli
from fabricsurf.cli.demo import demo_parser, parse, require, verify
from fabricsurf.discretise.output import on_rank0, write_json
from fabricsurf.inverse.contract.data import load_experiment
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.dic.export import spec_text, write_images
from fabricsurf.inverse.dic.frame import Frame
from fabricsurf.inverse.dic.layouts import LAYOUTS
from fabricsurf.inverse.dic.reader import find_header
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import rank0

ap = demo_parser(__doc__, "out/dic")  # --quick: the same run (see above)
ap.add_argument("--spacing", type=float, default=0.5, help="DIC point spacing (mm)")
ap.add_argument("--pitch", type=float, default=2.0, help="binning pitch of the import (mm)")
ap.add_argument(
    "--noise",
    type=float,
    default=0.05,
    help="displacement noise of one DIC point (mm, independent)",
)
ap.add_argument("--h", type=float, default=3.5, help="element size of the diagnosis (mm)")
args = parse(ap)
comm = MPI.COMM_WORLD
out = args.out
logger = logging.getLogger(__name__)


def say(msg: str) -> None:
    """Progress on rank 0, through the demo's logger (cli.demo.parse configures it)."""
    rank0(logger, comm, msg)


t_start = time.perf_counter()

# %% [markdown]
# ## 1. The truth at the DIC points
# The DIC subsets sit on a regular grid of the *camera* (every 10 pixels at 0.05 mm/pixel:
# 0.5 mm), which the tilt of 3° puts askew on the specimen; the points that fall on the
# specimen (1 mm clear of its edges) are kept.

# %%
L, W, PATH = 70.0, 35.0, [1.2, 2.4, 3.6]
TRUTH = {
    "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
    "shear": {"k_s": 0.5},
    "geodesic_bending": {"A_g": 15.0},
}
camera = Frame(scale=0.05, y_down=True, origin=(150.0, 900.0), grip="left", tilt_deg=3.0)
px = np.arange(0.0, 2000.0, args.spacing / camera.scale)
gx, gy = np.meshgrid(px, px, indexing="ij")
X = np.column_stack(camera.points(gx.ravel(), gy.ravel()))
X = X[(X[:, 0] > 1) & (X[:, 0] < L - 1) & (X[:, 1] > 1) & (X[:, 1] < W - 1)]
exp = sy.template(L, W, PATH, X, name="dic-bias")
sy.continuum_data(exp, full_model(list(TRUTH), TRUTH), h=2.2, comm=comm)
say(f"truth: {len(X)} DIC points per image, {len(PATH)} loaded images + 1 reference")
seconds = {"truth": time.perf_counter() - t_start}

# %% [markdown]
# ## 2. The export, as DICe writes it
# One `DICe_solution_NN.txt` per image: DICe's `***` preamble, its column names, coordinates in
# pixels from the image's upper-left corner with y pointing down, SIGMA = -1 where a subset
# failed (5 % of the points, at random), and independent noise of `--noise` mm on every
# displacement. Image 0 is the reference image (no load: noise only), images 1-3 the steps.
# The forces of a real test come from the machine's log (`[steps] force`); this demo is about
# the field and leaves them out.

# %%
rng = np.random.default_rng(2026)
U = [exp.u[exp.step_rows(s)] for s in exp.steps]
shots = [np.zeros_like(U[0])] + U
shots = [s + rng.normal(0.0, args.noise, s.shape) for s in shots]
export = out / "export"
files = on_rank0(
    comm, write_images, export, LAYOUTS["dice"], camera, [0, 1, 2, 3], X, shots, holes=0.05, seed=7
)
spec = out / "dic.toml"
on_rank0(
    comm,
    spec.write_text,
    spec_text(
        camera,
        name="dic-bias",
        layout="dice",
        files="export/DICe_solution_*.txt",
        length=L,
        width=W,
        reference_images=[0],
        images=[1, 2, 3],
        path=PATH,
        pitch=args.pitch,
    ),
)

comm.barrier()

# %% [markdown]
# ## 3. Import
# `fabricsurf import-dic` reads the four files, drops the holes, maps the points to the
# specimen's frame, bins them to 2 mm (about 16 points a bin) and estimates the noise level from
# the reference image's displacements, binned like the data: the expected value is
# noise / √(points per bin).

# %%
meas = out / "measured"
t0 = time.perf_counter()
require(cli(["import-dic", str(spec), "--out", str(meas)]) == 0)
seconds["import"] = time.perf_counter() - t0
data = load_experiment(meas)
report = json.loads((meas / "dic_import.json").read_text()) if comm.rank == 0 else None
report = comm.bcast(report)

# %% [markdown]
# ## 4. Is the imported field the truth? (a bias test of the import)
# The truth is solved again at the imported bins' mean points; the difference should be the
# bins' noise: mean ≈ 0 (no bias from the frame, scale or binning) and RMS ≈ the estimated
# noise_std.

# %%
t0 = time.perf_counter()
truth = sy.continuum_data(
    replace(data, u=np.zeros_like(data.u)), full_model(list(TRUTH), TRUTH), h=2.2
)
err = data.u - truth.u
seconds["check"] = time.perf_counter() - t0
per_bin = np.array([e["points"] / e["bins"] for e in report["files"]]).mean()
expected = args.noise / np.sqrt(per_bin)
bias = np.abs(err.mean(axis=0)) / (err.std(axis=0) / np.sqrt(len(err)))
say(
    f"import: {report['points_read']} points read, {report['holes']} holes dropped, "
    f"{report['rows_written']} rows; mean error {err.mean(axis=0)} mm "
    f"({bias.max():.2f} standard errors), RMS {err.std():.4f} mm, noise_std "
    f"{data.noise_std:.4f} mm (expected {expected:.4f} mm)"
)

# %% [markdown]
# ## 5. Diagnose
# The baseline `fibre_stretch + shear`, one effect added at most.

# %%
t0 = time.perf_counter()
cli(
    [
        "diagnose",
        str(meas),
        "--terms",
        "fibre_stretch,shear",
        "--h",
        str(args.h),
        "--confirm",
        "1",
        "--max-effects",
        "1",
        "--out",
        str(out / "diagnose"),
    ]
)
diag = json.loads((out / "diagnose" / "diagnosis.json").read_text()) if comm.rank == 0 else None
diag = comm.bcast(diag)
seconds["diagnose"] = time.perf_counter() - t0
final = diag["final"]["params"]
ratios = (
    {
        "k_s/k_l": final["shear"]["k_s"] / final["fibre_stretch"]["k_l"],
        "A_g/k_l": final["geodesic_bending"]["A_g"] / final["fibre_stretch"]["k_l"],
    }
    if diag["verdict"] == "geodesic_bending"
    else {}
)
say(
    f"moduli relative to k_l: {ratios} (truth k_s/k_l = {0.5 / 30:.4f}, A_g/k_l = 0.5); "
    "field-only data fix the ratios of the moduli, not their scale (a force column does)"
)

# %% [markdown]
# ## 6. Figures: the export as the camera sees it, and the imported field


# %%
def read_raw(path: Path) -> np.ndarray:
    """The numbers of an export file (columns as written: x, y, u, v, SIGMA)."""
    return np.loadtxt(path, delimiter=",", skiprows=find_header(Path(path))[0])


def figures() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    raw = read_raw(files[-1])
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    ok = raw[:, 4] != -1
    sc = ax[0].scatter(raw[ok, 0], raw[ok, 1], c=raw[ok, 2], s=1, cmap="viridis")
    ax[0].scatter(raw[~ok, 0], raw[~ok, 1], s=2, c="red", label="holes (SIGMA = -1)")
    ax[0].invert_yaxis()
    ax[0].set(
        title=f"{Path(files[-1]).name}: DISPLACEMENT_X (pixels)",
        xlabel="x (pixel)",
        ylabel="y (pixel, down)",
        aspect="equal",
    )
    ax[0].legend(loc="lower right", markerscale=4)
    fig.colorbar(sc, ax=ax[0])
    rows = data.step_rows(data.steps[-1])
    sc = ax[1].scatter(
        data.X[rows, 0],
        data.X[rows, 1],
        c=err[rows, 0],
        s=12,
        cmap="RdBu_r",
        vmin=-3 * expected,
        vmax=3 * expected,
    )
    ax[1].set(
        title="imported (2 mm bins) − truth, u_x (mm)",
        xlabel="X (mm)",
        ylabel="Y (mm)",
        aspect="equal",
        xlim=(0, L),
        ylim=(0, W),
    )
    fig.colorbar(sc, ax=ax[1])
    fig.tight_layout()
    fig.savefig(out / "dic_import.png", dpi=120)
    plt.close(fig)


on_rank0(comm, figures)

# %% [markdown]
# ## Checks
# The holes are the ones written; the import has no bias (mean error within 3 standard
# errors), its RMS error and the estimated noise level match noise/√(points per bin) within
# 15 %; the diagnosis names the hidden effect and the ratios of the fitted moduli are the
# truth's within 10 %.

# %%
holes_written = (
    sum(int((read_raw(f)[:, 4] == -1).sum()) for f in files[1:]) if comm.rank == 0 else None
)
truth_ratios = {"k_s/k_l": 0.5 / 30.0, "A_g/k_l": 15.0 / 30.0}
summary = {
    "points_per_image": len(X),
    "points_read": report["points_read"],
    "holes": report["holes"],
    "holes_as_written": report["holes"] == comm.bcast(holes_written),
    "rows_written": report["rows_written"],
    "mean_error_mm": err.mean(axis=0).tolist(),
    "bias_in_standard_errors": bias.max(),
    "rms_error_mm": float(err.std()),
    "noise_std_estimated": data.noise_std,
    "noise_std_expected": expected,
    "rms_error_vs_expected": float(err.std()) / expected,
    "noise_std_vs_expected": data.noise_std / expected,
    "baseline_misfit": diag["baseline"]["misfit"],
    "verdict": diag["verdict"],
    "ranking": [(r["effect"], r["score"]) for r in diag["ranking"]],
    "ratios": ratios,
    "ratios_vs_truth": [ratios[k] / truth_ratios[k] for k in ratios],
    "quick": args.quick,
    "seconds": time.perf_counter() - t_start,
    "seconds_per_stage": seconds,
}
write_json(comm, out / "summary.json", summary)
# the summary's contract, declared as the other demos declare theirs (tests/test_demos.py reads
# it from the source): (low, high) a range, ... present, anything else equal; "*" every element
CHECKS = {
    "verdict": "geodesic_bending",
    "holes": (1, None),
    "holes_as_written": True,
    "bias_in_standard_errors": (0.0, 3.0),
    "rms_error_vs_expected": (0.85, 1.15),
    "noise_std_vs_expected": (0.85, 1.15),
    "ratios_vs_truth/*": (0.9, 1.1),
    "seconds": ...,
}
require(len(summary["ratios_vs_truth"]) == 2, summary["verdict"])
verify(summary, CHECKS)
say(
    f"verdict {diag['verdict']}; figures in {out} and {out / 'diagnose'}; summary in "
    f"{out / 'summary.json'} ({summary['seconds']:.0f} s)"
)
