"""The hemisphere forming plug-in's internals (experiments/hemisphere.py): the blank, the tools
and their contact, friction, the contact Newton solver, options, profiles, the forming
indicators and the stroke log."""
