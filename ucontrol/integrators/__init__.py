"""How time advances.

:class:`MoreauJean` is imported with the package; :class:`EventDriven`, :class:`Compliant`
and the LZB impact law (which need ``scipy.integrate``) are imported on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ucontrol._lazy_names import lazy_names
from ucontrol.integrators.moreau_jean import MoreauJean

if TYPE_CHECKING:
    from ucontrol.integrators.compliant import Compliant
    from ucontrol.integrators.event_driven import EventDriven
    from ucontrol.integrators.lzb_impact import LZBImpactLaw, lzb_impact

_LAZY = {
    "Compliant": "ucontrol.integrators.compliant",
    "EventDriven": "ucontrol.integrators.event_driven",
    "LZBImpactLaw": "ucontrol.integrators.lzb_impact",
    "lzb_impact": "ucontrol.integrators.lzb_impact",
}

__all__ = ["Compliant", "EventDriven", "LZBImpactLaw", "MoreauJean", "lzb_impact"]


__getattr__ = lazy_names(__name__, _LAZY)
