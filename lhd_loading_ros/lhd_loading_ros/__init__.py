"""lhd_loading_ros: the ROS-free task core of the LHD loading project (config, pile, zones,
observation, reward, action filters, metrics), and the nodes and command line built on it."""
