"""What a run writes: run folders, logs, recordings (bags, LVX), and viewers (foxglove,
rerun, ROS 2)."""
