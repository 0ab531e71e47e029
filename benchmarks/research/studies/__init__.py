"""Studies built on the layers: dispersion, bias-test convergence and comparisons, woven fabric."""
