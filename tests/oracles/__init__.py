"""Readable numpy forms of the package's algorithms: the oracles its compiled kernels and
whole runs are checked against (never imported by the package)."""
