"""ROS-free task core: config, parameters, state, pile, zones, kinematics, observation, reward,
action filters and metrics. Imports nothing from ROS and nothing from the other rooms."""
