"""Photoreflective tactile sensing for soft robots."""
