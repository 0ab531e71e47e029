"""Reference solutions the discretisation is checked against, for the demos, the tests and a
user checking an installation or a new effect: the hyperbolic paraboloid, an exact solution of
the theory (``hypar.py``); the heavy elastica, the inextensible cantilever under its own weight,
with Peirce's bending length (``elastica.py``); the dispersion of chains and lattices against
gradient continua, Mühlhaus & Oka 1996 (``dispersion.py``); the bias test against the Hencky
and bi-pantographic lattices (``bias_comparison.py``), its grip force under refinement
(``bias_convergence.py``) and over the whole range (``bipantographic_range.py``); observed
rates and Richardson extrapolation (``rates.py``); the kinematic (fishnet) drape of a woven
net over a sphere (``fishnet.py``), a second drape sharing no code with it, the Chebyshev net
as a Goursat problem (``goursat_drape.py``), both against a continuum result
(``drape_map.py``, the forming plug-in's contact area ``forming_map.py``), the fishnet closed
from a continuum result's own generators (``generator_drape.py``); the flange's wrinkle
amplitude and a buckling estimate for the wrinkling indicator (``wrinkling.py``). What a demo
and its benchmark share on top of these is in :mod:`fabricsurf.studies`; no fitted or measured
numbers are held here. Imported on use: ``import fabricsurf.verification`` loads no FEniCSx
module."""
