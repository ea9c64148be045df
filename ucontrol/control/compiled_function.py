"""Moved to :mod:`ucontrol.model.compiled_function` (the contact layer compiles too)."""

from ucontrol.model.compiled_function import CompiledFunction

__all__ = ["CompiledFunction"]
