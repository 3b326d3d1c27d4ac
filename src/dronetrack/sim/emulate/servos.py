"""Emulated DYNAMIXEL XM430-W350 servos speaking Protocol 2.0 on a pseudo-terminal.

Three layers, each usable alone, each in a module of its own (importable from here):

* ``EmulatedXM430`` (``xm430``): one servo's control table (the subset that module
  lists, with the rules of writing it); joint motion is delegated to an injected
  ``JointModel``.
* ``ServoBus`` (``servo_bus``): the servos on one bus; turns each received packet
  into the status packets the protocol prescribes (none for broadcast reads and
  writes and for sync write; one per listed servo, in the listed order, for sync
  read; one per servo in ID order for a broadcast ping).
* ``PtyServoLink`` (``pty_link``): a pseudo-terminal in raw mode whose slave end is
  the serial device a driver opens (optionally reachable through a symlink), served
  by a background thread that stops on ``close()``, on its optional lifetime, or
  when the terminal goes away.
"""

from __future__ import annotations

from dronetrack.sim.emulate.pty_link import PtyServoLink
from dronetrack.sim.emulate.servo_bus import ServoBus, turret_bus
from dronetrack.sim.emulate.xm430 import (
    FIRMWARE_VERSION,
    MODEL_XM430_W350,
    EmulatedXM430,
    JointModel,
    RateLimitedJoint,
)

__all__ = [
    "FIRMWARE_VERSION",
    "MODEL_XM430_W350",
    "EmulatedXM430",
    "JointModel",
    "PtyServoLink",
    "RateLimitedJoint",
    "ServoBus",
    "turret_bus",
]
