"""Verification problems: manufactured solutions, hyperbolic paraboloid, rates, heavy elastica."""
