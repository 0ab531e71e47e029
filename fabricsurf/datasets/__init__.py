"""Measurement data shipped with the package, in the measurement-directory format
(docs/contracts.md), and a fit made on them; each function returns the directory for
``load_experiment`` or the file.

Real curves digitised from publications; see the README.md of each directory for the source,
the material and how the numbers were obtained.
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent


def woven_fit() -> Path:
    """The moduli of that fabric as the woven-fabric demo fits them (a ``--params`` file:
    ``{"terms", "params", "source"}``, its source the document that records the fit): the
    fabric the forming demo and its benchmark form when no params file of their own is given."""
    return HERE / "woven_fit_cao2008.json"


def cao2008_plain_weave() -> Path:
    """The bias-extension test of the plain-weave glass/polypropylene fabric of the woven-fabric
    benchmark (Cao et al. 2008, Fig. 38): 115 × 230 mm, ±45°, force only, 43 points."""
    return HERE / "cao2008_plain_weave_115x230"
