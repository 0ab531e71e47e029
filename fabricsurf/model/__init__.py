"""The model layer. Importing it loads the vocabulary of effects (``terms``), which registers
the effects of its sibling modules (``yarn_slip`` of ``slip``), so that any module of the layer
may be imported first."""

from fabricsurf.model import terms as _terms  # noqa: F401
