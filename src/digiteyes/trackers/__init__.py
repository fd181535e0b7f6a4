"""trackers layer (see DESIGN.md)."""
