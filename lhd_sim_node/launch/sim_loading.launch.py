"""ros2 launch lhd_sim_node sim_loading.launch.py [policy_dir:=DIR | controller:=tampier|teacher] [slope_deg:=20.0] [episodes:=N] [mode:=realtime]
    [namespace:=/lhd2] [use_sim_time:=true]

The sim node and the policy node (the shipped RLD actor unless policy_dir is given; controller:=tampier
or teacher runs the Tampier-style heuristic or the demonstrations' teacher instead), as
`lhd up sim` starts them where `ros2 launch` is not installed. With episodes:=N (N > 0) the launch ends after them, as
`lhd up sim --episodes N` does: the sim node's exit_when_done makes it exit 0 one second after the last episode ended,
and its exit shuts the launch down (the policy node gets launch's SIGINT and sends its last zero command); it prints
no results table (each episode's result is in the sim node's log and on /lhd/episode). episodes:=0 (the default) runs
until Ctrl-C. Under a namespace every /lhd
topic moves there, and /clock is remapped to the relative `clock` (so `<ns>/clock`; in the
root namespace that is /clock itself), as `lhd up sim --namespace` does."""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def text(name):
    """A string parameter (an empty or numeric-looking value stays a string)."""
    return ParameterValue(LaunchConfiguration(name), value_type=str)


def generate_launch_description():
    args = [
        DeclareLaunchArgument("policy_dir", default_value="", description="exported actor (default: shipped RLD)"),
        DeclareLaunchArgument("controller", default_value="actor", description="actor | tampier | teacher"),
        DeclareLaunchArgument("slope_deg", default_value="-1.0", description="pile slope, deg (negative: random)"),
        DeclareLaunchArgument("material", default_value="random", description="homogeneous | nonhomogeneous | random"),
        DeclareLaunchArgument("episodes", default_value="0", description="episodes to run, then the launch ends "
                              "(the sim node exits, exit_when_done); 0: no limit, until Ctrl-C"),
        DeclareLaunchArgument("mode", default_value="realtime", description="realtime | lockstep"),
        DeclareLaunchArgument("seed", default_value="0"),
        DeclareLaunchArgument("namespace", default_value="", description="e.g. /lhd2: two machines share a domain"),
        DeclareLaunchArgument("use_sim_time", default_value="false", description="nodes run on the sim's /clock"),
    ]
    ns = LaunchConfiguration("namespace")
    sim_time = ParameterValue(LaunchConfiguration("use_sim_time"), value_type=bool)
    clock = [("/clock", "clock")]
    lockstep = PythonExpression(["'", LaunchConfiguration("mode"), "' == 'lockstep'"])
    sim = Node(package="lhd_sim_node", executable="sim_node", name="lhd_sim", namespace=ns, output="screen",
               remappings=clock, parameters=[{"use_sim_time": sim_time,
        "mode": text("mode"), "slope_deg": ParameterValue(LaunchConfiguration("slope_deg"), value_type=float),
        "material": text("material"), "episodes": ParameterValue(LaunchConfiguration("episodes"), value_type=int),
        "exit_when_done": ParameterValue(PythonExpression([LaunchConfiguration("episodes"), " > 0"]), value_type=bool),
        "seed": ParameterValue(LaunchConfiguration("seed"), value_type=int)}])
    policy_common = {"policy_dir": text("policy_dir"), "controller": text("controller"), "use_sim_time": sim_time}
    policy_lockstep = Node(package="lhd_loading_ros", executable="policy_node", name="lhd_policy", namespace=ns, output="screen",
                           remappings=clock, parameters=[{**policy_common, "trigger": "lockstep", "input_qos": "reliable"}],
                           condition=IfCondition(lockstep))
    policy_timer = Node(package="lhd_loading_ros", executable="policy_node", name="lhd_policy", namespace=ns, output="screen",
                        remappings=clock, parameters=[{**policy_common, "trigger": "timer"}], condition=UnlessCondition(lockstep))
    # the sim node exits after the asked episodes (exit_when_done), or on an error: either way the launch ends
    end = RegisterEventHandler(OnProcessExit(target_action=sim, on_exit=[EmitEvent(event=Shutdown(
        reason="the sim node exited (its episodes done, or an error: see its log)"))]))
    return LaunchDescription([*args, sim, policy_lockstep, policy_timer, end])
