"""Errors of campaign files and campaign runs.

Every class derives from :class:`CampaignError`, itself a
:class:`ucontrol.exceptions.UControlError`, and carries the offending value as an attribute.
They are raised while a campaign file is read and checked, before any run starts (except
:class:`CampaignMismatchError`, raised when an output directory holds another campaign).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ucontrol.exceptions import InvalidParameterError, UControlError


class CampaignError(UControlError):
    """A campaign file or a campaign run is not usable; the message says why."""


class CampaignFileError(CampaignError):
    """A campaign file is missing, not TOML, or its tables are malformed.

    Attributes:
        path: The campaign file.
        reason: What is wrong.
    """

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"campaign file {path!r}: {reason}")


class ParameterKeyError(CampaignError, KeyError):
    """A dotted key does not address a value of the base scene (or the scene rejects it).

    Attributes:
        key: The dotted key, e.g. ``"contacts.0.restitution"``.
        reason: Why it does not apply.
    """

    def __init__(self, key: str, reason: str) -> None:
        self.key = key
        self.reason = reason
        super().__init__(f"parameter {key!r}: {reason}")

    def __str__(self) -> str:  # KeyError would print the repr of the message
        return str(self.args[0])


class DistributionError(CampaignError, InvalidParameterError):
    """A distribution's parameters are out of range.

    Attributes:
        key: The swept dotted key.
        name: The distribution parameter, e.g. ``"high"``.
        value: The value received.
        expected: What it must be.
    """

    def __init__(self, key: str, name: str, value: Any, expected: str) -> None:
        self.key = key
        UControlError.__init__(
            self, f"distribution of {key!r}: `{name}` must be {expected}, got {value!r}"
        )
        self.name = name
        self.value = value
        self.expected = expected


class EmptyGridError(CampaignError, InvalidParameterError):
    """A grid parameter has no values (the cartesian product would be empty).

    Attributes:
        key: The dotted key whose list of values is empty.
    """

    def __init__(self, key: str, value: Any) -> None:
        self.key = key
        UControlError.__init__(
            self, f"grid of {key!r} must be a non-empty list of values, got {value!r}"
        )
        self.name = key
        self.value = value
        self.expected = "a non-empty list of values"


class UnknownMetricError(CampaignError, KeyError):
    """A metric is neither a ``summary.json`` key, a verdict, nor an importable function.

    Attributes:
        metric: The metric asked for.
        reason: Why it is not available.
        available: The metric names that exist for this scene.
    """

    def __init__(self, metric: str, reason: str, available: Iterable[str] = ()) -> None:
        self.metric = metric
        self.reason = reason
        self.available = sorted(available)
        listed = f"; available: {', '.join(self.available)}" if self.available else ""
        super().__init__(f"unknown metric {metric!r}: {reason}{listed}")

    def __str__(self) -> str:
        return str(self.args[0])


class CriterionError(CampaignError, InvalidParameterError):
    """A success criterion is not a valid expression of the allowed form.

    Attributes:
        expression: The criterion text.
        reason: What is not allowed in it.
    """

    def __init__(self, expression: str, reason: str) -> None:
        self.expression = expression
        self.reason = reason
        UControlError.__init__(self, f"success criterion {expression!r}: {reason}")
        self.name = "success"
        self.value = expression
        self.expected = "a comparison of metrics (see docs/campaigns.md)"


class OutputDirectoryError(CampaignError, OSError):
    """The output directory cannot be created or written.

    Attributes:
        directory: The directory given with ``--out``.
        reason: The operating system's reason.
    """

    def __init__(self, directory: str, reason: str) -> None:
        self.directory = directory
        self.reason = reason
        UControlError.__init__(self, f"output directory {directory!r} is not writable: {reason}")

    def __str__(self) -> str:
        return str(self.args[0])


class CampaignMismatchError(CampaignError):
    """The output directory holds the runs of another campaign (different plan or metrics).

    Attributes:
        directory: The output directory.
        found: The fingerprint recorded there.
        expected: The fingerprint of the campaign being run.
    """

    def __init__(self, directory: str, found: str, expected: str) -> None:
        self.directory = directory
        self.found = found
        self.expected = expected
        super().__init__(
            f"{directory!r} holds another campaign (fingerprint {found[:12]}, this one "
            f"{expected[:12]}): choose another --out, or delete the directory to start again"
        )


class SchedulerUnreachableError(CampaignError, ConnectionError):
    """No Dask scheduler answered at the address given.

    Attributes:
        address: The scheduler address, e.g. ``"tcp://host:8786"``.
        reason: The connection error.
    """

    def __init__(self, address: str, reason: str) -> None:
        self.address = address
        self.reason = reason
        UControlError.__init__(self, f"no Dask scheduler reachable at {address!r}: {reason}")

    def __str__(self) -> str:
        return str(self.args[0])
