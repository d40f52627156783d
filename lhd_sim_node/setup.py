from setuptools import find_packages, setup

package_name = "lhd_sim_node"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", ["launch/sim_loading.launch.py", "launch/sim_nodes.launch.py"]),
    ],
    install_requires=["setuptools", "numpy", "mujoco", "gymnasium"],
    zip_safe=True,
    maintainer="lhd_loading maintainers",
    maintainer_email="maintainers@lhd-loading.dev",
    description="MuJoCo LHD simulator with the FEE pile force and the LhdLoading-v0 environment",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "scripted_demo = lhd_sim_node.demo:main",
            "sim_node = lhd_sim_node.sim_node:main",
            "twin_node = lhd_sim_node.twin_node:main",
        ],
    },
)
