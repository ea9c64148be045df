"""How time advances.

:class:`MoreauJean` is imported with the package; :class:`EventDriven` and :class:`Compliant`
(which need ``scipy.integrate``) are imported on first use.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from ucontrol.integrators.moreau_jean import MoreauJean

if TYPE_CHECKING:
    from ucontrol.integrators.compliant import Compliant
    from ucontrol.integrators.event_driven import EventDriven

_LAZY = {
    "Compliant": "ucontrol.integrators.compliant",
    "EventDriven": "ucontrol.integrators.event_driven",
}

__all__ = ["Compliant", "EventDriven", "MoreauJean"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
