"""The arm: robot models (URDF, xacro, MJCF, named arms), their terms, checks and reports."""
