"""The plant and the loop: sensors, constrained dynamics, the simulation step, the record."""
