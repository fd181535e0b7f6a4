"""smc layer (see DESIGN.md)."""
