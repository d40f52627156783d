"""ROS-free perception: ArUco marker pose and machine speed, LiDAR pile slope."""
