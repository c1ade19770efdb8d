"""studies layer (see DESIGN.md)."""
