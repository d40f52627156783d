"""lhd_hw_bridge: the Arduino Due serial bridge of the scaled LHD (protocol, bridge node,
device emulator). The package exists so the three-package layout builds with colcon; its
contents arrive with the serial-bridge issue."""
