"""Studies: what one demo and its benchmark share, built on the reference solutions of
``fabricsurf.verification`` and the experiment plug-ins, never imported by the library below
(docs/layout.md). The forming of a fitted woven fabric over a hemispherical punch: its set-up,
re-forming with other moduli, profiles against the fishnet drape and its figures
(``forming.py``; demos/demo_forming.py, benchmarks/forming.py); the Cao et al. 2008
bias-extension curve against the model: errors, the ranges no elastic term follows, the
large-shear record and the figures (``woven.py``; demos/demo_woven_fabric.py,
benchmarks/woven_real_yarns.py). They hold no fitted or measured numbers: a demo or benchmark
passes its moduli in, and the measured results live in the benchmarks and docs. Imported on
use: ``import fabricsurf.studies`` loads no FEniCSx module."""
