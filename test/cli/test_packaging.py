"""Packaging for users with a full ROS install: the launch file (skipped where `launch` is
not importable) and the entry points `ros2 run` looks for. The colcon build itself runs in
`make test` (Makefile target colcon-build) before the suite."""
import importlib.util
import os
from pathlib import Path

import pytest

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


def test_colcon_install_has_ros2_run_entry_points():
    """Checks the tree `make test` built with colcon (install/ at the repository root)."""
    install = ROOT / "install"
    if not (install / "lhd_sim_node").is_dir():
        pytest.skip("no colcon install tree (run `make colcon-build`, done by `make test`)")
    for pkg, exe in (("lhd_sim_node", "sim_node"), ("lhd_loading_ros", "policy_node"), ("lhd_loading_ros", "lhd"),
                     ("lhd_loading_ros", "aruco_pose_node"), ("lhd_loading_ros", "lidar_slope_node"),
                     ("lhd_hw_bridge", "bridge_node")):
        path = install / pkg / "lib" / pkg / exe
        assert path.is_file() and os.access(path, os.X_OK), path
    assert (install / "lhd_sim_node/share/lhd_sim_node/launch/sim_loading.launch.py").is_file()
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/config/lhd_params.yaml").is_file()
    assert (install / "lhd_loading_ros/share/lhd_loading_ros/policies/rld/policy.json").is_file()
