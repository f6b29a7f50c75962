"""Control laws, one module each, with their equations and sources in the docstring."""
