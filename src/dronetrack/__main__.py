"""``python -m dronetrack``."""

from dronetrack.cli import main

main()
