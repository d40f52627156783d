"""lhd_sim_node: MuJoCo simulator of the scaled LHD, the FEE pile force, the Gymnasium
environments ``LhdLoading-v0`` (in-process) and ``LhdLoadingRos-v0`` (through a running sim node,
ros_env.py), registered on import, and the ROS sim node."""
from gymnasium.envs.registration import register, registry

ENV_ID = "LhdLoading-v0"
ROS_ENV_ID = "LhdLoadingRos-v0"

if ENV_ID not in registry:
    register(id=ENV_ID, entry_point="lhd_sim_node.env:LhdLoadingEnv")
if ROS_ENV_ID not in registry:
    register(id=ROS_ENV_ID, entry_point="lhd_sim_node.ros_env:LhdLoadingRosEnv")
