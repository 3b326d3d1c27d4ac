"""Emulated devices: the simulator behind the real wire protocols, for the live drivers to
talk to (Livox LiDARs over UDP, Dynamixel servos on a pseudo-terminal)."""
