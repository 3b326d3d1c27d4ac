"""Turret control: aiming the sensor and scanning patterns."""
