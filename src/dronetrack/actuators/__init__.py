"""Turret commands out: the DYNAMIXEL servo turret, the FLIR PTU, ROS 2 turrets and the
command log of a replay."""
