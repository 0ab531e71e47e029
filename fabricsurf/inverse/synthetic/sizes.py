"""Synthetic pairs of specimen sizes with a hidden size effect, and the coverage of a prediction
band from one size to the other (docs/uncertainty.md, "Prediction to another size").

The data are force curves of the Hencky lattice in the bias test (force only, as the
Cao et al. curve), two specimens of the same lattice and aspect ratio, the second ``ratio``
times the size of the first, loaded to the same displacement per length (the same zone-C
shear). A first-gradient continuum (fibre stretch and shear) predicts the second force as
exactly ``ratio`` times the first: whatever departs from that is a size effect, hidden from the
fitted model:

- ``bending``: the lattice's fibres resist in-plane bending (bending length ``l_b`` = 4 mm):
  boundary layers along the zone boundaries and the grips, a larger share of a smaller specimen;
- ``discreteness``: a coarse lattice (spacing 2.5 mm, bending length 1 mm): half cells at the
  free edges and the grips, whose share falls with the size.

Two fabrics: ``soft`` fibres (k_l/k_s = 60) and ``stiff`` ones (k_l/k_s = 2500). The model is
fitted on the first specimen with the fibres' stiffness held (known, as the yarns' in the
woven demo) and the shear modulus free; the band of the second specimen's prediction is then
checked against its points.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.contract.experiment import Experiment, template
from fabricsurf.log import detail

FABRICS = {"soft": (30.0, 0.5, 0.3), "stiff": (1000.0, 0.4, 0.2)}
"""k_l (N/mm), k_s (N/mm), the largest displacement per length."""

HIDDEN = {"bending": (4.0, 1.0), "discreteness": (1.0, 2.5)}
"""Bending length l_b (mm; A_g = k_s l_b²) and lattice spacing (mm) of each hidden effect."""

NOISE = 0.01
"""Force noise: this share of the largest force of each curve (as the woven demo's unit)."""


def curve(
    length: float, width: float, fabric: str, effect: str, steps: int, seed: int
) -> tuple[Experiment, Experiment]:
    """(noisy, clean) force-only lattice curves of a ``length`` × ``width`` specimen."""
    from fabricsurf.inverse.synthetic.generate import add_noise, lattice_data

    k_l, k_s, strain = FABRICS[fabric]
    l_b, spacing = HIDDEN[effect]
    path = np.linspace(strain * length / steps, strain * length, steps)
    exp = template(
        length, width, path, np.zeros((0, 2)), name=f"{fabric} {effect} {length:g} x {width:g} mm"
    )
    exp = lattice_data(exp, spacing, k_l=k_l, k_s=k_s, A_g=k_s * l_b**2, every=10**9)
    clean = replace(exp, field_step=np.zeros(0, int), X=np.zeros((0, 2)), u=np.zeros((0, 2)))
    s_F = NOISE * float(np.max(np.abs(clean.force)))
    return add_noise(replace(clean), 0.0, s_F, seed), clean


def base_model(fabric: str, k_s: float | None = None) -> list:
    """Fibre stretch (the lattice's, held) and shear, at ``k_s`` (default the lattice's)."""
    from fabricsurf.model.terms import parse_terms

    k_l, k_s0, _ = FABRICS[fabric]
    return parse_terms(
        "fibre_stretch,shear",
        {"fibre_stretch": {"k_l": k_l, "k_m": k_l}, "shear": {"k_s": k_s0 if k_s is None else k_s}},
    )


def pair_coverage(
    calib: Experiment,
    other: Experiment,
    fabric: str,
    h: float,
    comm: MPI.Comm = MPI.COMM_WORLD,
    candidates=None,
    other_clean: np.ndarray | None = None,
) -> dict:
    """Fit the shear modulus on ``calib`` (mesh h), estimate the size part there, predict
    ``other`` (h scaled with the size: the same mesh in the specimen's units) with its band,
    and count the points of ``other`` inside it, with and without the size part, and those of
    its noise-free force ``other_clean`` when given (the curve the band is a band of)."""
    from fabricsurf.inverse.fitting import size_form as sz
    from fabricsurf.inverse.fitting.band import predicted_band
    from fabricsurf.inverse.fitting.fit import fit
    from fabricsurf.inverse.forward.runs import ForwardModel

    start = 1.3 * FABRICS[fabric][1]
    with ForwardModel(calib, base_model(fabric, start), h=h, comm=comm) as fm:
        free = [fm.names.index("shear.k_s")]
        with detail():  # the calibrating fit: detail of the coverage study (DEBUG)
            res = fit(fm, free, scale_start=False, space="linear")
        res.check_mesh(fm)
    fitted = base_model(fabric, float(res.values[free[0]]))
    ext = sz.extended_model(fitted, candidates or sz.SIZE_CANDIDATES)
    with ForwardModel(calib, ext, h=h, comm=comm) as fm:
        res.size_effects = sz.size_record(
            fm, ["shear.k_s"], res.chi2, h, calib.width, candidates or sz.SIZE_CANDIDATES
        )
    scale = other.length / calib.length
    band = predicted_band(
        res.as_dict(), fitted, other.length, other.width, other.path, h * scale, comm=comm
    )
    F, half = np.array(band["force"]), np.array(band["half_width"])
    p = band["parts"]
    without = np.sqrt(np.square(p["statistical"]) + np.square(p["model_form"])) + p["mesh"]
    err = np.abs(other.force - F)
    fmax = float(np.max(np.abs(other.force)))
    return {
        "k_s": float(res.values[free[0]]),
        "k_s_ci95": res.as_dict()["moduli"]["shear.k_s"]["ci95"],
        "points": len(F),
        "coverage": float(np.mean(err <= half)),
        "coverage_without_size": float(np.mean(err <= without)),
        "mean_half_width_pct": 100 * float(np.mean(half)) / fmax,
        "mean_half_width_without_pct": 100 * float(np.mean(without)) / fmax,
        "max_error_pct": 100 * float(np.max(err)) / fmax,
        "coverage_clean": None
        if other_clean is None
        else float(np.mean(np.abs(np.asarray(other_clean) - F) <= half)),
        "size_effects": res.size_effects,
        "reliable": band["reliable"],
    }
