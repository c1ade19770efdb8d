"""nodes layer (see DESIGN.md)."""
