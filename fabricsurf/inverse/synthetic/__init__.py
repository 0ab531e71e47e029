"""Synthetic measurement data with a hidden effect (continuum or Hencky lattice, plus noise)."""
