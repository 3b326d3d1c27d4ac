"""The simulated rig behind the run loop's seams: the world is a Source, its turret an
Actuator, and the truth aimer a Sink that steers the turret at the true target.

The world's clock is the run's: frames come one integration period apart from
``world.time``, and a command acts from its stamp (plus the turret's own latency).
"""

from __future__ import annotations

from collections.abc import Iterator

from dronetrack.control.aiming import aim_angles
from dronetrack.sim.world import SimWorld
from dronetrack.types import Sample, StepResult, TurretCommand, TurretState

__all__ = ["SimSource", "SimTurret", "TruthAimer"]


class SimSource:
    """``n_frames`` frames of the world, each made only when the loop asks for it, so the
    previous frame's command has reached the turret."""

    def __init__(self, world: SimWorld, n_frames: int) -> None:
        self.world = world
        self.n_frames = n_frames

    @property
    def period(self) -> float:
        return self.world.integration_time

    def __len__(self) -> int:
        return self.n_frames

    def __iter__(self) -> Iterator[Sample]:
        for _ in range(self.n_frames):
            frame, truth = self.world.step()
            yield Sample(frame, truth, truth.turret)


class SimTurret:
    """The world's turret as an Actuator: goals act from their stamp on."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world

    def command(self, command: TurretCommand) -> None:
        self.world.command(command)

    def state(self) -> TurretState:
        return self.world.turret_state()


class TruthAimer:
    """Steers the turret at the true target after every tracking frame, the way an
    operator followed the drone for seed 000's Table III, so that every tracker sees
    the same frames.  Pair it with the ``truth`` turret mode, whose controller leaves
    the turret alone while tracking.

    The goal is the target's position at the command's stamp: the frame's end plus
    ``latency_s``, as the pipeline stamps its own commands.
    """

    def __init__(self, world: SimWorld, latency_s: float) -> None:
        self.world = world
        self.latency_s = latency_s

    def write(self, sample: Sample, result: StepResult) -> None:
        if result.phase != "track":
            return
        t = sample.frame.end + self.latency_s
        pan, tilt = aim_angles(self.world.target_position(t), self.world.mount)
        self.world.command(TurretCommand(t, pan, tilt))
