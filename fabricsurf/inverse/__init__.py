"""The inverse layer: contract (measurement data) <- fitting <- plots, synthetic."""
