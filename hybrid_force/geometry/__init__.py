"""Where the tool works: surfaces Φ(p) and task paths p_d(t)."""
