"""The ROS nodes of this package, one module each, thin over task/, policy/ and perception/."""
