"""solvers layer (see DESIGN.md)."""
