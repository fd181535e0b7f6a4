"""occlusion layer (see DESIGN.md)."""
