"""``python -m dronetrack``."""

from dronetrack.cli.main import main

main()
