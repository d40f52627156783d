"""ros2 launch lhd_loading_ros real_machine.launch.py port:=/dev/ttyACM0 [controller:=rld|rlc|tampier|teacher|teleop]
    [policy_dir:=DIR] [config:=lhd_params.yaml] [camera_topic:=/camera/image_raw] [camera_info_topic:=/camera/camera_info]
    [scan_topic:=/scan] [end_zone:=lidar|FILE.yaml] [joy_mapping:=xbox] [material:=homogeneous]
    [run_dir:=runs/real/NAME] [attempt_timeout:=10.0] [teleop_attempt_timeout:=40.0] [record:=true] [storage:=mcap]
    [params_file:=<share>/config/real_machine.yaml] [joy:=true]

The real-machine stack, as `lhd up real` starts it where `ros2 launch` is not installed: bridge,
ArUco pose, LiDAR slope, end zone, supervisor, command mux, teleop (and the `joy` driver when
joy:=true), the controller on /lhd/cmd/auto (none for controller:=teleop) and the recorder.
The calibration comes from params_file (every node reads its own section). Before any node
starts, the file is checked as `lhd up real` checks it (cli/up_real.stack_problem: one name for
the pile frame in every node; a controller rate of at least 2 commands per timeout of the mux's
auto source): the launch ends with the reason instead. docs/real_machine.md."""
import os
from datetime import datetime, timezone
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def text(name):
    """A string parameter (an empty or numeric-looking value stays a string)."""
    return ParameterValue(LaunchConfiguration(name), value_type=str)


def refuse_unsound_params(context):
    """Resolves the actor, the parameter file and the supervisor's slope limits as `lhd up real` does
    (cli/up_real.machine_actor: controller:=rld / rlc without policy_dir runs the machine's actor,
    policies/rld_drift_confirm_margin8 or rlc_gains, with its own lhd_params.yaml unless config:= or $LHD_CONFIG names
    another), then raises (the launch ends, naming the problem, before any node starts) when params_file
    would leave every attempt without zones or commands, or the actor does not fit the parameter file;
    returns the launch configurations the nodes read (actor_dir, actor_config, slope_limits, and the supervisor's
    required_listeners, as `lhd up real` sets them: an attempt armed before the recorder, the mux or the
    controller heard /lhd/episode had no bag or did not move)."""
    from launch.actions import SetLaunchConfiguration

    from types import SimpleNamespace

    from lhd_loading_ros.cli.up_real import machine_actor, required_listeners, stack_problem
    from lhd_loading_ros.policy.actor_file import PolicyFileError, load_policy
    from lhd_loading_ros.task.config import ConfigError, load_config

    params_file = LaunchConfiguration("params_file").perform(context)
    controller = LaunchConfiguration("controller").perform(context)
    if not Path(params_file).is_file():
        raise RuntimeError(f"real_machine.launch.py: params_file {params_file!r} does not exist")
    try:
        root = os.path.join(get_package_share_directory("lhd_loading_ros"), "policies")
    except Exception:  # noqa: BLE001 - not installed (a source tree): actor_file.default_policy_dir finds them
        root = None
    chosen = machine_actor(controller, LaunchConfiguration("policy_dir").perform(context),
                           LaunchConfiguration("config").perform(context), policies_root=root)
    problem = stack_problem(Path(params_file), controller, chosen.config or None)
    if problem:
        raise RuntimeError(f"real_machine.launch.py refuses to start the stack: {problem}")
    if chosen.policy:
        try:
            load_policy(chosen.policy).check_config(load_config(chosen.config or None))
        except (PolicyFileError, ConfigError) as exc:
            raise RuntimeError(f"real_machine.launch.py refuses to start the stack: {exc}") from None
    if chosen.note:
        print(f"real_machine.launch.py: {chosen.note}", flush=True)
    limits = list(chosen.slope_limits) if chosen.slope_limits else [0.0, 90.0]
    record = context.launch_configurations.get("record", "true").strip().lower() in ("true", "1")   # as IfCondition
    listeners = required_listeners(SimpleNamespace(controller=controller, record=record))
    return [SetLaunchConfiguration("actor_dir", chosen.policy), SetLaunchConfiguration("actor_config", chosen.config),
            SetLaunchConfiguration("slope_limits", f"[{limits[0]:.1f}, {limits[1]:.1f}]"),
            SetLaunchConfiguration("required_listeners", "[" + ", ".join(f"'{n}'" for n in listeners) + "]")]


def generate_launch_description():
    share = get_package_share_directory("lhd_loading_ros")
    stamp = datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S")
    args = [
        DeclareLaunchArgument("port", description="serial device of the Due, e.g. /dev/ttyACM0"),
        DeclareLaunchArgument("controller", default_value="rld", description="rld | rlc | tampier | teacher | teleop"),
        DeclareLaunchArgument("policy_dir", default_value="", description="exported actor (default: the machine's, "
                              "policies/rld_drift_confirm_margin8 or rlc_gains: docs/real_machine.md)"),
        DeclareLaunchArgument("config", default_value="", description="lhd_params.yaml for every node (default: the "
                              "actor's own where it ships one, else the package's)"),
        DeclareLaunchArgument("camera_topic", default_value="/camera/image_raw"),
        DeclareLaunchArgument("camera_info_topic", default_value="/camera/camera_info"),
        DeclareLaunchArgument("scan_topic", default_value="/scan"),
        DeclareLaunchArgument("end_zone", default_value="lidar", description="lidar | a surveyed YAML file"),
        DeclareLaunchArgument("joy_mapping", default_value="xbox", description="xbox | ps4 | f710 | game_controller"),
        DeclareLaunchArgument("joy", default_value="true", description="start the joy driver (package joy)"),
        DeclareLaunchArgument("material", default_value="homogeneous", description="homogeneous | nonhomogeneous"),
        DeclareLaunchArgument("run_dir", default_value=os.path.join("runs", "real", stamp)),
        DeclareLaunchArgument("attempt_timeout", default_value="10.0", description="s (the paper: 10 s)"),
        DeclareLaunchArgument("teleop_attempt_timeout", default_value="40.0",
                              description="s, a teleoperated attempt's (the paper's operators took 10-16 s on average)"),
        DeclareLaunchArgument("record", default_value="true", description="one rosbag2 per attempt"),
        DeclareLaunchArgument("storage", default_value="mcap", description="mcap | sqlite3"),
        DeclareLaunchArgument("params_file", default_value=os.path.join(share, "config", "real_machine.yaml")),
    ]
    pf = LaunchConfiguration("params_file")
    controller = LaunchConfiguration("controller")
    is_lidar = PythonExpression(["'", LaunchConfiguration("end_zone"), "' == 'lidar'"])
    policy_dir = LaunchConfiguration("actor_dir")          # set by refuse_unsound_params (machine_actor)
    config = {"config": ParameterValue(LaunchConfiguration("actor_config"), value_type=str)}
    nodes = [
        Node(package="lhd_hw_bridge", executable="bridge_node", name="lhd_hw_bridge", output="screen",
             parameters=[pf, {"port": text("port"), **config}]),
        Node(package="lhd_loading_ros", executable="aruco_pose_node", name="aruco_pose_node", output="screen",
             parameters=[pf, {"image_topic": text("camera_topic"), "camera_info_topic": text("camera_info_topic")}]),
        Node(package="lhd_loading_ros", executable="lidar_slope_node", name="lidar_slope_node", output="screen",
             parameters=[pf, {"scan_topic": text("scan_topic")}]),
        Node(package="lhd_loading_ros", executable="end_zone_node", name="end_zone_node", output="screen",
             parameters=[pf, {**config, "source": PythonExpression(["'lidar' if ", is_lidar, " else 'surveyed'"]),
                              "surveyed_file": PythonExpression(["'' if ", is_lidar, " else '",
                                                                 LaunchConfiguration("end_zone"), "'"])}]),
        Node(package="lhd_loading_ros", executable="supervisor_node", name="lhd_supervisor", output="screen",
             parameters=[pf, {**config, "run_dir": text("run_dir"), "controller": text("controller"),
                              "policy_dir": ParameterValue(policy_dir, value_type=str), "material": text("material"),
                              # a YAML list from the launch configuration, "[10.0, 35.0]"
                              "slope_limits_deg": LaunchConfiguration("slope_limits"),
                              "required_listeners": LaunchConfiguration("required_listeners"),
                              "attempt_timeout": ParameterValue(LaunchConfiguration("attempt_timeout"),
                                                                value_type=float),
                              "teleop_attempt_timeout": ParameterValue(LaunchConfiguration("teleop_attempt_timeout"),
                                                                       value_type=float)}]),
        Node(package="lhd_loading_ros", executable="cmd_mux_node", name="lhd_cmd_mux", output="screen",
             parameters=[pf, config]),
        Node(package="lhd_loading_ros", executable="teleop_node", name="lhd_teleop", output="screen",
             parameters=[pf, {**config, "mapping": text("joy_mapping")}]),
        Node(package="joy", executable="joy_node", name="joy_node", output="screen",
             condition=IfCondition(LaunchConfiguration("joy"))),
        Node(package="lhd_loading_ros", executable="policy_node", name="lhd_policy", output="screen",
             # through the mux (a parameter, not a remap: a remap of /lhd/cmd missed under a namespace)
             parameters=[pf, {**config, "cmd_topic": "cmd/auto", "policy_dir": ParameterValue(policy_dir, value_type=str),
                              "controller": PythonExpression(["'", controller, "' if '", controller,
                                                              "' in ('tampier', 'teacher') else 'actor'"])}],
             condition=IfCondition(PythonExpression(["'", controller, "' != 'teleop'"]))),
        Node(package="lhd_loading_ros", executable="recorder_node", name="lhd_recorder", output="screen",
             parameters=[pf, {"run_dir": text("run_dir"), "storage": text("storage")}],
             condition=IfCondition(LaunchConfiguration("record"))),
    ]
    return LaunchDescription([*args, OpaqueFunction(function=refuse_unsound_params), *nodes])
