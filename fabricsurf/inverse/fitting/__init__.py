"""Forward model with sensitivities, misfit, fit, diagnosis, significance, moduli files."""
