"""Uncertainty of fitted moduli: statistical (correlated residuals), intervals and what the
data determine, and the systematic parts (mesh and model form)."""
