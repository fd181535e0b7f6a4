"""templates layer (see DESIGN.md)."""
