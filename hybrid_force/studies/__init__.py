"""Edges that run many scenarios: sweeps and comparisons (nothing in the core imports them)."""
