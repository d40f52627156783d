import os
from glob import glob

from setuptools import find_packages, setup

package_name = "lhd_loading_ros"
here = os.path.dirname(os.path.abspath(__file__))

data_files = [
    ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
    ("share/" + package_name, ["package.xml"]),
]
# The shared parameter files live in <repo>/config; colcon installs a copy into share/.
config_files = glob(os.path.join(os.path.relpath(os.path.join(here, "..", "config")), "*.yaml"))
if config_files:
    data_files.append(("share/" + package_name + "/config", config_files))
# Gamepad mappings of the teleop node: config/teleop/*.yaml -> share/lhd_loading_ros/config/teleop/
teleop_files = glob(os.path.join(os.path.relpath(os.path.join(here, "..", "config", "teleop")), "*.yaml"))
if teleop_files:
    data_files.append(("share/" + package_name + "/config/teleop", teleop_files))
# The real-machine launch file (what `lhd up real` starts)
launch_files = glob(os.path.join("launch", "*.launch.py"))
if launch_files:
    data_files.append(("share/" + package_name + "/launch", launch_files))
# The shipped actors (<repo>/policies/<variant>/) go to share/lhd_loading_ros/policies/<variant>/,
# where the policy node looks for its default actor in an installed workspace.
for variant in ("rld", "rlc", "rld_dr", "rld_paper", "rld_margin", "rld_twin", "rlc_twin", "rlc_twin_mass", "rlc_twin_sil_bc",
                "rld_gains", "rlc_gains", "rld_lidar", "rld_told_teacher", "rld_machine",
                "rld_drift_confirm", "rld_drift_confirm_margin8", "rlc_drift_confirm_margin8"):   # policies/README.md says what each is
    files = sorted(glob(os.path.join(os.path.relpath(os.path.join(here, "..", "policies", variant)), "*")))
    if files:
        data_files.append(("share/" + package_name + "/policies/" + variant, files))

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=data_files,
    install_requires=["setuptools", "numpy", "pyyaml", "opencv-python-headless"],
    zip_safe=True,
    maintainer="lhd_loading maintainers",
    maintainer_email="maintainers@lhd-loading.dev",
    description="Task core, training, policy and perception nodes, and the lhd command line",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "lhd = lhd_loading_ros.cli.main:main",
            "policy_node = lhd_loading_ros.nodes.policy_node:main",
            "aruco_pose_node = lhd_loading_ros.nodes.aruco_pose_node:main",
            "lidar_slope_node = lhd_loading_ros.nodes.lidar_slope_node:main",
            "end_zone_node = lhd_loading_ros.nodes.end_zone_node:main",
            "supervisor_node = lhd_loading_ros.nodes.supervisor_node:main",
            "cmd_mux_node = lhd_loading_ros.nodes.cmd_mux_node:main",
            "teleop_node = lhd_loading_ros.nodes.teleop_node:main",
            "recorder_node = lhd_loading_ros.nodes.recorder_node:main",
        ],
    },
)
