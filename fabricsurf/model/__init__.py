"""The model layer: kinematics, the energy terms (``term.py`` the base class, ``terms.py`` the
vocabulary of effects, ``slip.py`` yarn slip) and what a term knows about itself (its shear
moment in pure shear, ``pure_shear.py``). The modules import one way, with no circle: any of them
may be imported first."""
