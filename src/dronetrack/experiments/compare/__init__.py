"""Side-by-side comparisons of the seeds' methods: ``dronetrack compare``."""
