"""Forming references: the kinematic drape (fishnet) of a hemisphere."""
