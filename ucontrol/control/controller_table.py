"""Parts of a ``[controller]`` table that several controller types share."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from ucontrol._validation import check_keys, require_key
from ucontrol.contact.point_contact import PointContact
from ucontrol.control.desired_cycle import ContactPhase, DesiredCycle
from ucontrol.exceptions import NotFoundError

#: Settings of the designed cycle a table may give (the fields of :class:`DesiredCycle`
#: besides its path and contact phases).
CYCLE_KEYS = tuple(
    field.name
    for field in dataclasses.fields(DesiredCycle)
    if field.name not in ("path", "contact_phases")
)
#: Keys of each ``[[controller.contact_phases]]`` entry.
CONTACT_PHASE_KEYS = ("contact", "start", "end", "force")


def tracked_contacts(
    table: Mapping[str, Any], frame: str, contacts: Sequence[PointContact]
) -> list[PointContact]:
    """The contacts a controller tracks: ``contacts`` by name, default every one on ``frame``.

    Raises:
        NotFoundError: A name that is no contact of the scene (the message lists them).
    """
    by_name = {contact.name: contact for contact in contacts}
    names = table.get("contacts", [c.name for c in contacts if c.frame == frame])
    for name in names:
        if name not in by_name:
            raise NotFoundError("contact", str(name), by_name)
    return [by_name[name] for name in names]


def contact_phases(table: Mapping[str, Any]) -> tuple[ContactPhase, ...]:
    """The ``[[controller.contact_phases]]`` entries of a table (none when absent).

    Raises:
        SceneError: An entry lacks a key.
        UnknownKeyError: An entry holds a key beyond :data:`CONTACT_PHASE_KEYS`.
    """
    entry = "[[controller.contact_phases]]"
    phases = []
    for spec in table.get("contact_phases", []):
        check_keys(entry, spec, set(CONTACT_PHASE_KEYS))
        phases.append(
            ContactPhase(**{key: require_key(spec, entry, key) for key in CONTACT_PHASE_KEYS})
        )
    return tuple(phases)
