"""Measurement data shipped with the package, in the measurement-directory format
(docs/contracts.md); each function returns the directory for ``load_experiment``.

Real curves digitised from publications; see the README.md of each directory for the source,
the material and how the numbers were obtained.
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent


def cao2008_plain_weave() -> Path:
    """The bias-extension test of the plain-weave glass/polypropylene fabric of the woven-fabric
    benchmark (Cao et al. 2008, Fig. 38): 115 × 230 mm, ±45°, force only, 43 points."""
    return HERE / "cao2008_plain_weave_115x230"
