"""A stand-in for the episode supervisor in its own process: <prefix>/episode saying `running`
(episode key argv[1]; "-": a status without one) at the supervisor's STATUS_HZ (2 Hz), latched like its status, until killed.
The node tests kill or stop this process to play a supervisor that crashed or hung: SIGKILL leaves
no DDS goodbye, so the graph keeps listing its publisher until its lease expires (about 20 s)."""
import sys

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from lhd_loading_ros.nodes.supervisor_node import STATUS_HZ
from lhd_loading_ros.ros.qos import STATUS_QOS


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("stand_in_supervisor")
    pub = node.create_publisher(DiagnosticStatus, "/lhd/episode", STATUS_QOS)
    key = [] if sys.argv[1] == "-" else [KeyValue(key="episode", value=sys.argv[1])]   # "-": no key (a third party's)
    st = DiagnosticStatus(name="lhd attempt", message="running", values=[KeyValue(key="state", value="running"), *key])
    node.create_timer(1.0 / STATUS_HZ, lambda: pub.publish(st))
    pub.publish(st)
    print("publishing", flush=True)
    rclpy.spin(node)


if __name__ == "__main__":
    main()
