"""Scenario files: TOML → a checked :class:`~hybrid_force.sim.settings.Scenario` (an edge:
nothing in the core imports it). The loader is :mod:`hybrid_force.scenario.loader`."""
