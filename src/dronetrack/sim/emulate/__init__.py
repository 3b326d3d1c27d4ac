"""Emulated devices: simulated sensors and actuators that speak the real wire protocols."""
