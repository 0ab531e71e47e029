"""Research code behind the figures and calibrations of docs/ (not installed, see
benchmarks/README.md)."""
