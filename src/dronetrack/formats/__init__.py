"""Bytes to arrays and back: the devices' wire protocols (livox, DYNAMIXEL, PTU,
VLP-16), ROS messages (ros) and files (PCD, LZF, tables, background maps)."""
