"""The noise level of an import: given, or estimated (binning.noise_estimate) from reference
images that carry information, or else from the steps.

A reference image correlated with itself (DICe's frame 0, DaVis's first image) holds
displacements of round-off size, 1e-15 pixel or 8e-13 mm: no scatter of the correlation, so
no noise information. Such an image (every |u| ≤ ROUNDOFF × the specimen size) is a
zero-displacement image; the noise is then estimated from the steps, and the report says so.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.dic.binning import noise_estimate
from fabricsurf.inverse.dic.description.spec import ImportSpec

ROUNDOFF = 1e-9
"""Displacements below this fraction of the specimen size are round-off: double precision of
coordinates of 10³–10⁴ pixels is 1e-13–1e-12, exports print it as 1e-15–1e-12 mm, while the
scatter of a real static image pair is 1e-3–1e-2 pixel, 1e-5–1e-3 mm, ≥ 1e-7 of a specimen:
1e-9 lies three decades above the one and two below the other."""
NO_SCATTER = 1e-9
"""An estimated noise level below this fraction of the specimen size is no scatter at all
(noise-free data): no estimate is recorded (the contract's default applies)."""


def roundoff_images(spec: ImportSpec, entries: list[dict]) -> list[int]:
    """The images among ``entries`` (report entries with ``max_abs_u_mm``) of round-off size."""
    size = max(spec.setup.length, spec.setup.width)
    return [e["image"] for e in entries if e["max_abs_u_mm"] <= ROUNDOFF * size]


def noise(
    spec: ImportSpec,
    refs: tuple | None,
    ref_entries: list[dict],
    step: np.ndarray,
    X: np.ndarray,
    u: np.ndarray,
) -> dict:
    """{"noise_std", "method", "estimate"[, "roundoff_reference_images"]} (mm)."""
    if spec.noise_std is not None:
        return {"noise_std": spec.noise_std, "method": "given in [data] noise_std"}
    size = max(spec.setup.length, spec.setup.width)
    flat = roundoff_images(spec, ref_entries)
    note = ""
    if flat:
        largest = max(e["max_abs_u_mm"] for e in ref_entries if e["image"] in flat)
        note = (
            f"; reference image(s) {flat} hold round-off displacements only (largest |u| "
            f"{largest:.2g} mm ≤ {ROUNDOFF:g} × the specimen size): zero-displacement "
            "images without noise information, not used for it"
        )
    useful = [k for k, e in enumerate(ref_entries, start=1) if e["image"] not in flat]
    if refs is not None and useful:
        keep = np.isin(refs[0], useful)
        est = noise_estimate(refs[0][keep], refs[1][keep], refs[2][keep])
        method = "estimated: local plane residuals of the reference images' displacements" + (
            " (binned as the data)" if spec.pitch else ""
        )
    else:
        est = noise_estimate(step, X, u)
        method = "estimated: local plane residuals of the written field, all steps"
    out = {"roundoff_reference_images": flat} if flat else {}
    if est["noise_std"] is None or est["noise_std"] < NO_SCATTER * size:
        why = "too few points" if est["noise_std"] is None else "the data show no scatter"
        return out | {
            "noise_std": None,
            "estimate": est,
            "method": f"not estimated: {why}; give [data] noise_std (the contract's "
            "default applies: 1 % of the largest displacement)" + note,
        }
    return out | {"noise_std": est["noise_std"], "method": method + note, "estimate": est}
