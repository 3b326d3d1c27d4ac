"""Evaluation: metrics and plots over logged runs, simulated or recorded."""
