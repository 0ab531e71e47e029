"""Kinematic drapes over a punch (fishnet, Goursat net, the continuum's own generators)
and the maps that compare a continuum forming result with them."""
