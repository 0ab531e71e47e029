"""Verification problems not installed: manufactured solutions (the installed references, the
hyperbolic paraboloid, the heavy elastica and rates, are in fabricsurf.verification)."""
