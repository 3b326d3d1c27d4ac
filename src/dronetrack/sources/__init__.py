"""Frames in: live LiDAR clients (livox, velodyne, ros2) and recordings, as the run
loop's sources."""
