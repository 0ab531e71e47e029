"""The hemisphere forming plug-in's internals (experiments/hemisphere.py): the blank, the tools
and their contact, friction, the contact Newton solver, options, profiles, the forming
indicators, the stroke log and what the plug-in reads off the formed blank."""
