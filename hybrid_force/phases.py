"""The phases of a run (paper section 6.4): free space, near the surface, in contact.

One definition for the supervisor that switches them, the result that stores them per
sample, and the figures and the replay that show them. A result's ``phase`` array holds the
codes as int64: 2 (contact) exactly when the tool is on the surface, else the supervisor's
approach phase.
"""

from __future__ import annotations

from enum import IntEnum

__all__ = ["CONTACT", "FREE", "NEAR", "PHASE_NAMES", "Phase"]


class Phase(IntEnum):
    """Phase code of a sample: 0 free, 1 near, 2 contact."""

    FREE = 0
    NEAR = 1
    CONTACT = 2

    @property
    def label(self) -> str:
        """Lower-case name, as events and figures spell it ("free", "near", "contact")."""
        return self.name.lower()


#: Plain integer codes, for the simulation loop and its compiled recorder.
FREE, NEAR, CONTACT = int(Phase.FREE), int(Phase.NEAR), int(Phase.CONTACT)
#: Names by code: PHASE_NAMES[code].
PHASE_NAMES: tuple[str, ...] = tuple(p.label for p in Phase)
