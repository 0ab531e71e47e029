"""What demos/demo_woven_fabric.py and demos/demo_forming.py still import from the research tree
until they run from the installed package alone (issue 42; the other demos do)."""
