"""Scenario files: TOML → a checked :class:`~hybrid_force.sim.loop.Scenario` (an edge: nothing
in the core imports it). The loader is :mod:`hybrid_force.scenario.loader`."""

from hybrid_force.scenario.loader import (
    ON_SURFACE_TOL,
    RobotTable,
    load_scenario,
    parse_override,
    read_scenario_document,
    resolve_robot_table,
    scenario_from_document,
    xacro_argument_text,
)

__all__ = [
    "ON_SURFACE_TOL",
    "RobotTable",
    "load_scenario",
    "parse_override",
    "read_scenario_document",
    "resolve_robot_table",
    "scenario_from_document",
    "xacro_argument_text",
]
