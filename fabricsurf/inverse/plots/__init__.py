"""Figures of model vs measurement and the comparison outputs (misfit JSON, CSV, figures)."""
