"""A meshcat viewer without server: it records the commands a drawing sends."""

from __future__ import annotations

from typing import Any

import meshcat


class RecordingWindow:
    """Stands for meshcat's ``ViewerWindow``: keeps every command, lowered to a dict."""

    def __init__(self) -> None:
        self.commands: list[dict[str, Any]] = []

    def send(self, command: Any) -> None:
        self.commands.append(command.lower())

    def objects(self) -> dict[str, dict[str, Any]]:
        """The last ``set_object`` of each path."""
        return {c["path"]: c["object"] for c in self.commands if c["type"] == "set_object"}

    def properties(self, path: str) -> dict[str, Any]:
        """The last value of each property set on ``path``."""
        return {
            c["property"]: c["value"]
            for c in self.commands
            if c["type"] == "set_property" and c["path"] == path
        }


def recording_viewer() -> tuple[meshcat.Visualizer, RecordingWindow]:
    """A meshcat viewer whose commands are recorded instead of sent to a server."""
    window = RecordingWindow()
    return meshcat.Visualizer(window=window), window
