"""Which physical effect is missing: the stepwise diagnosis, its significance rule, ties, the
grip-depth nuisance, the separating experiment and the choice of mesh."""
