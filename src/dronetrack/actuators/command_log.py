"""An actuator that executes nothing: the turret commands of a replay, kept for the record."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from dronetrack.types import TurretCommand, TurretState

__all__ = ["CommandLog", "write_commands_csv"]


class CommandLog:
    """Keeps every command (a recording's turret already moved as it did); reports no state."""

    def __init__(self) -> None:
        self.commands: list[TurretCommand] = []

    def command(self, command: TurretCommand) -> None:
        self.commands.append(command)

    def state(self) -> TurretState | None:
        return None


def write_commands_csv(commands: Sequence[TurretCommand], path: Path) -> None:
    """The turret commands the pipeline issued (logged, not executed): t, mode, pan, tilt."""
    with path.open("w") as fh:
        fh.write("t,mode,pan_rad,tilt_rad\n")
        for c in commands:
            fh.write(f"{c.stamp:.6f},{c.mode},{c.pan:.6f},{c.tilt:.6f}\n")
