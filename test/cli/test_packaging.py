"""Packaging for users with a full ROS install: the launch file (skipped where `launch` is
not importable), the entry points `ros2 run` looks for, and those entry points started as
processes from a sourced workspace. The colcon build itself runs in `make test` (Makefile
target colcon-build) before the suite; without an install tree these tests skip."""
import ast
import importlib.util
import math
import os
import re
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import rclpy
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState, LaserScan
from std_msgs.msg import Bool, Float64, Float64MultiArray

from lhd_loading_ros.perception.synthetic import synthetic_scan

from rosutil import init_ros, shutdown_ros, spin_until, unique_domain_id

ROOT = Path(__file__).resolve().parents[2]


def test_launch_file_describes_both_nodes():
    pytest.importorskip("launch")
    pytest.importorskip("launch_ros")
    spec = importlib.util.spec_from_file_location("sim_loading", ROOT / "lhd_sim_node/launch/sim_loading.launch.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ld = mod.generate_launch_description()
    execs = {getattr(e, "node_executable", None) for e in ld.entities}
    assert {"sim_node", "policy_node"} <= execs
    # the launch ends when the sim node exits (its episodes done: exit_when_done)
    from launch.actions import RegisterEventHandler
    assert any(isinstance(e, RegisterEventHandler) for e in ld.entities)


def test_sim_nodes_launch_file_declares_its_arguments():
    pytest.importorskip("launch")
    pytest.importorskip("launch_ros")
    from launch.actions import DeclareLaunchArgument, OpaqueFunction

    spec = importlib.util.spec_from_file_location("sim_nodes", ROOT / "lhd_sim_node/launch/sim_nodes.launch.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ld = mod.generate_launch_description()
    names = {e.name for e in ld.entities if isinstance(e, DeclareLaunchArgument)}
    assert {"count", "namespace_base", "config", "seed"} <= names
    assert any(isinstance(e, OpaqueFunction) for e in ld.entities)


def test_real_machine_launch_file_describes_the_stack():
    pytest.importorskip("launch")
    pytest.importorskip("launch_ros")
    spec = importlib.util.spec_from_file_location("real_machine", ROOT / "lhd_loading_ros/launch/real_machine.launch.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ld = mod.generate_launch_description()
    execs = {getattr(e, "node_executable", None) for e in ld.entities}
    assert {"bridge_node", "aruco_pose_node", "lidar_slope_node", "end_zone_node", "supervisor_node", "cmd_mux_node",
            "teleop_node", "policy_node", "recorder_node"} <= execs


def test_real_machine_launch_file_checks_its_parameters_before_any_node(tmp_path):
    """The launch file runs `lhd up real`'s checks (cli/up_real.stack_problem) in an OpaqueFunction
    ahead of every node: a launch whose params_file names the pile frame apart, or sets a controller
    too slow for the mux, ends with the reason and starts nothing."""
    pytest.importorskip("launch")
    pytest.importorskip("launch_ros")
    from launch import LaunchContext
    from launch.actions import OpaqueFunction
    from launch_ros.actions import Node

    from lhd_loading_ros.cli.up_real import default_params_file

    spec = importlib.util.spec_from_file_location("real_machine", ROOT / "lhd_loading_ros/launch/real_machine.launch.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ents = mod.generate_launch_description().entities
    check = next(k for k, e in enumerate(ents) if isinstance(e, OpaqueFunction))
    assert check < min(k for k, e in enumerate(ents) if isinstance(e, Node))
    slow = tmp_path / "slow.yaml"
    slow.write_text("lhd_policy:\n  ros__parameters:\n    rate_hz: 3.0\n")
    frames = tmp_path / "frames.yaml"
    frames.write_text("lidar_slope_node:\n  ros__parameters:\n    frame_id: drawpoint_3\n")

    def run_check(params_file, controller="rld"):
        ctx = LaunchContext()
        ctx.launch_configurations.update({"params_file": str(params_file), "controller": controller,
                                          "policy_dir": "", "config": ""})
        return mod.refuse_unsound_params(ctx)

    from launch.actions import SetLaunchConfiguration

    def configs(actions):
        assert all(isinstance(a, SetLaunchConfiguration) for a in actions)
        ctx = LaunchContext()
        for a in actions:
            a.execute(ctx)
        return {k: ctx.launch_configurations[k] for k in ("actor_dir", "actor_config", "slope_limits",
                                                           "required_listeners")}

    got = configs(run_check(default_params_file()))     # the machine's RLD, its own file, its validated slopes
    assert got["actor_dir"].endswith("rld_drift_confirm_margin8")
    assert got["actor_config"].endswith("rld_drift_confirm_margin8/lhd_params.yaml")
    assert got["slope_limits"] == "[10.0, 35.0]"
    assert got["required_listeners"] == "['lhd_cmd_mux', 'lhd_policy', 'lhd_recorder']"     # as `lhd up real` sets
    assert configs(run_check(slow, "teleop")) == {"actor_dir": "", "actor_config": "", "slope_limits": "[0.0, 90.0]",
                                                  "required_listeners": "['lhd_cmd_mux', 'lhd_recorder']"}
    with pytest.raises(RuntimeError, match="every attempt would end as lost_input"):
        run_check(slow)
    with pytest.raises(RuntimeError, match="expected one name for the pile frame"):
        run_check(frames, "teleop")
    with pytest.raises(RuntimeError, match="does not exist"):
        run_check(tmp_path / "missing.yaml")


def test_colcon_install_has_ros2_run_entry_points():
    """Checks the tree `make test` built with colcon (install/ at the repository root)."""
    install = ROOT / "install"
    if not (install / "lhd_sim_node").is_dir():
        pytest.skip("no colcon install tree (run `make colcon-build`, done by `make test`)")
    for pkg, exe in (("lhd_sim_node", "sim_node"), ("lhd_loading_ros", "policy_node"), ("lhd_loading_ros", "lhd"),
                     ("lhd_loading_ros", "aruco_pose_node"), ("lhd_loading_ros", "lidar_slope_node"),
                     ("lhd_hw_bridge", "bridge_node"), ("lhd_loading_ros", "end_zone_node"),
                     ("lhd_loading_ros", "supervisor_node"), ("lhd_loading_ros", "cmd_mux_node"),
                     ("lhd_loading_ros", "teleop_node"), ("lhd_loading_ros", "recorder_node")):
        path = install / pkg / "lib" / pkg / exe
        assert path.is_file() and os.access(path, os.X_OK), path
    assert (install / "lhd_sim_node/share/lhd_sim_node/launch/sim_loading.launch.py").is_file()
    assert (install / "lhd_sim_node/share/lhd_sim_node/launch/sim_nodes.launch.py").is_file()
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/config/lhd_params.yaml").is_file()
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/config/real_machine.yaml").is_file()
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/config/teleop/xbox.yaml").is_file()
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/launch/real_machine.launch.py").is_file()
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/policies/rld/policy.json").is_file()
    # an actor with its own parameter file travels with it (policies/rld_twin: 10-35 deg piles)
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/policies/rld_twin/lhd_params.yaml").is_file()


def sourced_workspace_env() -> dict:
    """The environment of a ROS user's shell: the Python that has rclpy first on PATH (here the
    project's .venv; on a full ROS install /usr/bin), then `. install/setup.sh`. Taken from a
    real sourcing of colcon's script, not rebuilt by hand."""
    base = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH")}
    base["PATH"] = f"{Path(sys.executable).parent}:{base.get('PATH', '/usr/bin:/bin')}"
    out = subprocess.run(["bash", "-c", f". '{ROOT}/install/setup.sh' >/dev/null && env -0"], env=base,
                         capture_output=True, check=True).stdout
    env = dict(kv.split("=", 1) for kv in out.decode().split("\0") if "=" in kv)
    assert str(ROOT / "install/lhd_loading_ros/lib/python3") in env["PYTHONPATH"], env.get("PYTHONPATH")
    # PYTHONVERBOSE: the process itself logs the file of every module it imports
    return dict(env, ROS_DOMAIN_ID=str(unique_domain_id()), PYTHONUNBUFFERED="1", PYTHONVERBOSE="1")


class Installed:
    """An installed executable started as it is, by its path (its shebang picks the Python)."""

    def __init__(self, pkg: str, exe: str, args: list[str], env: dict, log_path: Path):
        self.path = ROOT / "install" / pkg / "lib" / pkg / exe
        self.name, self.log_path = exe, log_path
        self._log = open(log_path, "w")
        self.proc = subprocess.Popen([str(self.path), *args], stdout=self._log, stderr=subprocess.STDOUT, env=env,
                                     start_new_session=True)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def project_modules(self) -> set[str]:
        """Files of the project's modules this process imported (from its PYTHONVERBOSE log)."""
        found = re.findall(r"^# code object from '?([^'\n]+)'?$", self.log(), re.M)
        return {f for f in found if re.search(r"/(lhd_loading_ros|lhd_sim_node|lhd_hw_bridge)/", f)}

    def stop(self) -> int:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self._log.close()
        return self.proc.returncode


def needs_install_tree():
    if not (ROOT / "install" / "lhd_sim_node").is_dir():
        pytest.skip("no colcon install tree (run `make colcon-build`, done by `make test`)")


def assert_ran_installed_code(p: Installed):
    mods = p.project_modules()
    assert mods, f"{p.name}: no project module imported?\n{p.log()[-3000:]}"
    outside = sorted(m for m in mods if not m.startswith(str(ROOT / "install")))
    assert not outside, f"{p.name} imported project modules from outside the install tree: {outside[:5]}"


@pytest.fixture
def ros_node():
    init_ros()
    node = rclpy.create_node("packaging_test")
    yield node
    node.destroy_node()
    shutdown_ros()


@pytest.mark.parallel_safe     # waits up to 90 s for each publication: not timing-sensitive (test/conftest.py)
def test_installed_sim_policy_and_perception_nodes_run_and_publish(ros_node, tmp_path):
    """`ros2 run`'s view: install/<pkg>/lib/<pkg>/<exe> in a sourced workspace. Before the
    shebang fix these started the build tool's Python (.venv-colcon: no rclpy, no numpy)."""
    needs_install_tree()
    env = sourced_workspace_env()
    node = ros_node
    got = {k: [] for k in ("joint_states", "cmd", "stale", "slope")}
    node.create_subscription(JointState, "/lhd/joint_states", got["joint_states"].append, 10)
    node.create_subscription(Float64MultiArray, "/lhd/cmd", got["cmd"].append, 10)
    node.create_subscription(Bool, "/lhd/aruco/stale", got["stale"].append, 10)
    node.create_subscription(Float64, "/lhd/pile/slope", got["slope"].append, 10)
    pub_scan = node.create_publisher(LaserScan, "/lidar/scan", qos_profile_sensor_data)
    procs = [Installed("lhd_sim_node", "sim_node", ["--ros-args", "-p", "slope_deg:=20.0"], env, tmp_path / "sim.log"),
             Installed("lhd_loading_ros", "policy_node", [], env, tmp_path / "policy.log"),
             Installed("lhd_loading_ros", "aruco_pose_node", [], env, tmp_path / "aruco.log"),
             Installed("lhd_loading_ros", "lidar_slope_node", [], env, tmp_path / "lidar.log")]
    try:
        alive_logs = lambda: "\n".join(f"--- {p.name} (rc {p.proc.poll()}):\n{p.log()[-1500:]}" for p in procs)
        assert spin_until(node, lambda: node.count_subscribers("/lidar/scan") > 0, 90.0), alive_logs()
        r, amin, inc, _ = synthetic_scan(math.radians(20.0), np.random.default_rng(0))
        scan = LaserScan(angle_min=float(amin), angle_increment=float(inc), range_min=0.05, range_max=30.0,
                         ranges=[float(v) for v in r])
        scan.angle_max = float(amin + inc * (len(r) - 1))
        scan.header.frame_id = "lidar"

        def all_heard():
            if not any(abs(math.degrees(s.data) - 20.0) < 1.0 for s in got["slope"][-3:]):
                scan.header.stamp = node.get_clock().now().to_msg()
                pub_scan.publish(scan)
            return all(got.values())

        assert spin_until(node, all_heard, 90.0, step=0.1), ({k: len(v) for k, v in got.items()}, alive_logs())
        for p in procs:
            assert p.proc.poll() is None, alive_logs()
            assert_ran_installed_code(p)
    finally:
        codes = {p.name: p.stop() for p in procs}
    assert codes == {p.name: 0 for p in procs}, alive_logs()


def test_installed_bridge_node_runs_against_the_installed_device_emulator(ros_node, tmp_path):
    needs_install_tree()
    env = sourced_workspace_env()
    node = ros_node
    link = tmp_path / "due"
    js = []
    node.create_subscription(JointState, "/lhd/joint_states", js.append, 10)
    dev = Installed("lhd_hw_bridge", "lhd-fake-due", ["--link", str(link)], env, tmp_path / "due.log")
    procs = [dev]
    try:
        t_end = time.monotonic() + 60
        while not link.exists() and time.monotonic() < t_end and dev.proc.poll() is None:
            time.sleep(0.1)
        assert link.exists(), dev.log()[-3000:]
        bridge = Installed("lhd_hw_bridge", "bridge_node", ["--ros-args", "-p", f"port:={link}"], env,
                           tmp_path / "bridge.log")
        procs.insert(0, bridge)
        assert spin_until(node, lambda: len(js) >= 3, 90.0), bridge.log()[-3000:]
        assert list(js[-1].name)[:2] == ["boom", "bucket"]
        for p in procs:
            assert_ran_installed_code(p)
    finally:
        codes = {p.name: p.stop() for p in procs}
    assert codes["bridge_node"] == 0, bridge.log()[-3000:]


# --- package.xml declares every import ---------------------------------------------------------
# ROS packages: the import name is the package name and the rosdep key.
ROS_IMPORTS = {"rclpy", "rcl_interfaces", "builtin_interfaces", "ament_index_python", "launch", "launch_ros",
               "visualization_msgs",
               "std_msgs", "std_srvs", "sensor_msgs", "nav_msgs", "geometry_msgs", "diagnostic_msgs",
               "rosgraph_msgs", "lhd_loading_ros", "lhd_sim_node", "lhd_hw_bridge"}
# Python libraries: import name -> rosdep key (rosdistro's rosdep/python.yaml). A system package
# where one exists; `-pip` keys where rosdep knows only the PyPI package.
PYTHON_KEYS = {
    "numpy": "python3-numpy",
    "rosbags": "python3-rosbags-pip",
    "yaml": "python3-yaml",
    "cv2": "python3-opencv",
    "serial": "python3-serial",          # pyserial
    "matplotlib": "python3-matplotlib",
    "torch": "python3-torch",
    "numba": "python3-numba",
    "mujoco": "python3-mujoco-pip",
    "gymnasium": "python3-gymnasium-pip",
    "PIL": "python3-pil",                # Pillow: lhd replay --video writes GIFs
}
# Imports deliberately not declared, with the reason; each must sit inside a function, so that
# importing the package's modules never needs them.
UNDECLARED = {
    ("lhd_loading_ros", "lhd_sim_node"): "lhd demo|up|train|eval import the simulator; it depends on us (no cycle)",
    ("lhd_loading_ros", "lhd_hw_bridge"): "lhd bench bridge; it depends on us (no cycle)",
    ("lhd_loading_ros", "stable_baselines3"): "optional: lhd bench train --vs-sb3 only",
    ("lhd_loading_ros", "imageio_ffmpeg"): "optional: lhd replay --video OUT.mp4 only (GIF needs only Pillow)",
    ("lhd_loading_ros", "ray"): "optional: lhd sweep only (requirements.txt installs it; no rosdep key)",
    ("lhd_sim_node", "llvmlite"): "numba's own dependency (python3-numba installs it): loads libmujoco for fused.py",
}
PACKAGES = ("lhd_loading_ros", "lhd_sim_node", "lhd_hw_bridge")
# ROS packages a launch file starts (not imported): (package, key) -> the launch file that needs it
LAUNCHED = {("lhd_loading_ros", "joy"): "launch/real_machine.launch.py starts joy_node"}


def package_imports(pkg: str) -> dict[str, list[tuple[str, bool]]]:
    """Top-level import names of a package's modules and launch files (setup.py excluded: build
    time), each with where it is and whether it is at module level."""
    found: dict[str, list[tuple[str, bool]]] = {}
    files = sorted((ROOT / pkg / pkg).rglob("*.py")) + sorted((ROOT / pkg).glob("launch/*.py"))
    for f in files:
        tree = ast.parse(f.read_text(), str(f))
        top = {id(n) for n in tree.body}
        top |= {id(n) for s in tree.body if isinstance(s, (ast.If, ast.Try)) for n in ast.walk(s)}
        for n in ast.walk(tree):
            if isinstance(n, ast.Import):
                names = [a.name for a in n.names]
            elif isinstance(n, ast.ImportFrom) and n.level == 0:
                names = [n.module]
            else:
                continue
            for name in names:
                root = name.split(".")[0]
                if root not in sys.stdlib_module_names and root != pkg:
                    found.setdefault(root, []).append((f"{f.relative_to(ROOT)}:{n.lineno}", id(n) in top))
    return found


def declared_exec_depends(pkg: str) -> dict[str, dict]:
    root = ET.parse(ROOT / pkg / "package.xml").getroot()
    return {e.text.strip(): e.attrib for e in root.findall("exec_depend")}


@pytest.mark.parametrize("pkg", PACKAGES)
def test_package_xml_declares_every_import(pkg):
    imports = package_imports(pkg)
    declared = declared_exec_depends(pkg)
    needed, problems = set(), []
    for name, where in sorted(imports.items()):
        if (pkg, name) in UNDECLARED:
            at_top = [w for w, top in where if top]
            assert not at_top, f"{name} ({UNDECLARED[pkg, name]}) must be imported inside a function: {at_top}"
            continue
        key = name if name in ROS_IMPORTS else PYTHON_KEYS.get(name)
        if key is None:
            problems.append(f"{name} (at {where[0][0]}): unknown import; add its rosdep key to PYTHON_KEYS "
                            "(or a reason to UNDECLARED) in this test, and the key to package.xml")
        elif key not in declared:
            problems.append(f"{name} (at {where[0][0]}) needs <exec_depend>{key}</exec_depend> in {pkg}/package.xml")
        needed.add(key)
    for (p, key), why in LAUNCHED.items():
        if p == pkg:
            assert key in declared, f"{pkg}/package.xml must declare {key}: {why}"
            needed.add(key)
    unused = sorted(set(declared) - needed)
    assert not problems, "\n".join(problems)
    assert not unused, f"{pkg}/package.xml declares exec_depends nothing imports: {unused}"


def test_package_xml_states_the_opencv_the_aruco_code_needs():
    """cv2.aruco.ArucoDetector arrived in OpenCV 4.7.0; distributions ship older builds."""
    assert declared_exec_depends("lhd_loading_ros")["python3-opencv"] == {"version_gte": "4.7.0"}


def test_the_import_check_catches_an_undeclared_import(tmp_path, monkeypatch):
    """The check above can fail: a package whose module imports scipy and yaml, with yaml only."""
    pkg = tmp_path / "demo_pkg"
    (pkg / "demo_pkg").mkdir(parents=True)
    (pkg / "demo_pkg" / "m.py").write_text("import yaml\n\ndef f():\n    from scipy import linalg\n")
    (pkg / "package.xml").write_text("<package format='3'><name>demo_pkg</name>"
                                     "<exec_depend>python3-yaml</exec_depend></package>")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert set(package_imports("demo_pkg")) == {"yaml", "scipy"}
    with pytest.raises(AssertionError, match="scipy .*unknown import"):
        test_package_xml_declares_every_import("demo_pkg")
