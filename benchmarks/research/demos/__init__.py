"""What the demos share and what they would otherwise carry: the declared checks of a demo's
summary.json, its command line (quiet compiler unless ``--verbose``), and the figure and
comparison code of the longer demos (not installed, see benchmarks/README.md)."""
