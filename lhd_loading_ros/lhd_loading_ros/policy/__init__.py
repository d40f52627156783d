"""The exported actor (file format, numpy forward pass) and the ROS-free decision core that the
policy node runs every cycle."""
