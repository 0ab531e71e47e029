"""The forward model of experiments with exact sensitivities to the moduli: its observations,
misfit and tall-Jacobian algebra, warm starts and rank-local solves."""
