"""lhd_sim_node: MuJoCo simulator of the scaled LHD, the FEE pile force, the Gymnasium
environment ``LhdLoading-v0`` (registered on import) and the ROS sim node."""
from gymnasium.envs.registration import register, registry

ENV_ID = "LhdLoading-v0"

if ENV_ID not in registry:
    register(id=ENV_ID, entry_point="lhd_sim_node.env:LhdLoadingEnv")
