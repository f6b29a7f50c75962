"""Edges that draw a result: figures and the 3D replay (nothing in the core imports them)."""
