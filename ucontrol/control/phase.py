r"""Phases of a cycle with unilateral contacts and the events that separate them.

Cycle k of a contact (Brogliato, ch. 8): the free phase :math:`\Omega_{2k}`, the transition
:math:`I_k = [\tau_0, t_f]` (approach from :math:`\tau_0`, first impact :math:`t_0`,
accumulation of impacts until :math:`t_f`), the constrained phase
:math:`\Omega_{2k+1} = [t_f, t_d]` and the takeoff at :math:`t_d`, which starts the next free
phase.
"""

from __future__ import annotations

from enum import IntEnum, IntFlag


class Phase(IntEnum):
    """Phase of one contact (and, in the log, of the whole cycle); stored as an integer."""

    FREE = 0
    """Free motion on the nominal path (:math:`\\Omega_{2k}`)."""
    APPROACH = 1
    """From :math:`\\tau_0` to the first impact: virtual target below the surface."""
    TRANSITION = 2
    """From the first impact :math:`t_0` to the end of the accumulation :math:`t_f`."""
    CONSTRAINED = 3
    """On the surface with a desired contact force (:math:`\\Omega_{2k+1}`)."""
    TAKEOFF = 4
    """From :math:`t_d`: leaving the surface and joining the nominal path."""


#: Phases of the transition :math:`I_k`, where V may jump.
TRANSITION_PHASES = (Phase.APPROACH, Phase.TRANSITION)

#: The phase reported for the whole cycle is the first of this list held by some contact.
PHASE_PRIORITY = (Phase.TRANSITION, Phase.APPROACH, Phase.CONSTRAINED, Phase.TAKEOFF)


class Event(IntFlag):
    """Events of one contact at one sample; stored as integer bit flags."""

    NONE = 0
    TAU0 = 1
    """:math:`\\tau_0`: the approach starts."""
    FIRST_IMPACT = 2
    """:math:`t_0`: the first impact of the cycle was seen."""
    ACCUMULATION_END = 4
    """:math:`t_f`: the impacts have accumulated, the contact is persistent."""
    TAKEOFF = 8
    """:math:`t_d`: the constrained phase ends, the takeoff starts."""


def overall_phase(phases: list[Phase]) -> Phase:
    """Phase of the cycle from the phases of its contacts (see :data:`PHASE_PRIORITY`)."""
    for phase in PHASE_PRIORITY:
        if phase in phases:
            return phase
    return Phase.FREE
