"""fabricsurf: woven fabric sheets as second-gradient elastic surfaces on FEniCSx."""

__version__ = "0.2.0"
