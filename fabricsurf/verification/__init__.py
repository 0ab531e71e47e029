"""Reference solutions the discretisation is checked against, for the demos, the tests and a
user checking an installation or a new effect: the hyperbolic paraboloid, an exact solution of
the theory (``hypar.py``); the heavy elastica, the inextensible cantilever under its own weight,
with Peirce's bending length (``elastica.py``); the dispersion of chains and lattices against
gradient continua, Mühlhaus & Oka 1996 (``dispersion.py``); the bias test against the Hencky
and bi-pantographic lattices (``bias_comparison.py``), its grip force under refinement
(``bias_convergence.py``) and over the whole range (``bipantographic_range.py``); observed
rates and Richardson extrapolation (``rates.py``); the real plain-weave curve of Cao et al. 2008
against the model: fitted range, errors and the ranges no elastic term follows (``woven.py``);
the kinematic (fishnet) drape of a woven net over a sphere (``fishnet.py``) and the forming
study built on it: set-up, re-forming, shear maps and figures (``forming.py``).
Imported on use: ``import
fabricsurf.verification`` loads no FEniCSx module."""
