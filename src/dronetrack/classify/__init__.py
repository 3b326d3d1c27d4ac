"""What each track is: a drone, a bird, a static object or unknown, from the track's
life (``features``), by measured rules (``rules``), among them whether it returns
more often than the drone could at its range (``return_share``)."""
