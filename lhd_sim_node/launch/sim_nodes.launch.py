"""ros2 launch lhd_sim_node sim_nodes.launch.py [count:=2] [namespace_base:=/sim] [config:=FILE] [seed:=0]

N lockstep sim nodes for learners, in namespaces <namespace_base>0 .. <namespace_base>N-1, no policy
node: what `lhd up sim --count N` starts where `ros2 launch` is not installed. Then
`lhd train --variant rld --env ros --namespaces /sim0,/sim1` (docs/training.md "Where to train").
Node i's own seed is seed + 1,000,000 i (a learner sets each episode's seed anyway); each node
publishes its sim time on <namespace>/clock."""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _sim_nodes(context):
    try:
        n = int(LaunchConfiguration("count").perform(context))
        seed = int(LaunchConfiguration("seed").perform(context))
    except ValueError as exc:
        raise RuntimeError(f"count and seed must be integers: {exc}") from None
    if not 1 <= n <= 64:
        raise RuntimeError(f"count:={n}; expected 1..64 sim nodes")
    base = "/" + LaunchConfiguration("namespace_base").perform(context).strip("/")
    config = LaunchConfiguration("config").perform(context)
    nodes = []
    for i in range(n):
        params = {"mode": "lockstep", "seed": seed + 1_000_000 * i, "auto_reset": True}
        if config:
            params["config"] = config
        nodes.append(Node(package="lhd_sim_node", executable="sim_node", name="lhd_sim", namespace=f"{base}{i}",
                          output="screen", remappings=[("/clock", "clock")], parameters=[params]))
    return nodes


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("count", default_value="2", description="number of sim nodes (1..64)"),
        DeclareLaunchArgument("namespace_base", default_value="/sim", description="namespaces /sim0, /sim1, ..."),
        DeclareLaunchArgument("config", default_value="", description="lhd_params.yaml (default: the package's)"),
        DeclareLaunchArgument("seed", default_value="0"),
        OpaqueFunction(function=_sim_nodes),
    ])
