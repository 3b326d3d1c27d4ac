"""Trackers: seed 000's particle filter (and, later, the Kalman-family baselines)."""
