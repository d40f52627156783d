from setuptools import find_packages, setup

package_name = "lhd_hw_bridge"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/firmware/lhd_due", ["lhd_hw_bridge/firmware/lhd_due/lhd_due.ino",
                                                   "lhd_hw_bridge/firmware/lhd_due/arm_rate.h"]),
    ],
    install_requires=["setuptools", "pyserial"],
    zip_safe=True,
    maintainer="lhd_loading maintainers",
    maintainer_email="maintainers@lhd-loading.dev",
    description="Arduino Due serial bridge of the scaled LHD",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "bridge_node = lhd_hw_bridge.bridge_node:main",
            "lhd-fake-due = lhd_hw_bridge.fake_due:main",
        ],
    },
)
