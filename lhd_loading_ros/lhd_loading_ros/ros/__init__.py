"""ROS plumbing shared by every node: the run loop, QoS profiles, parameter declaration and
checks, diagnostics."""
