"""The supervisor node ends a running attempt whose commands stopped reaching the machine, as
real processes over DDS: the command mux's latched /lhd/cmd_mux/active leaving `auto` (the
controller stalled: lost_input; the gamepad took over: aborted) and the bridge's own command
watchdog in /lhd/hw/status (`command_stale`: the mux stalled). Before 2026-11-28 a controller or
mux stalled for 2 s drove on afterwards and the attempt was recorded as a success (a review's
fault injection on the twin). The rule itself: test/task/test_attempt.py."""
import math
import time

import pytest
import rclpy
from std_msgs.msg import Float64, Float64MultiArray, String

from fake_machine import LATCHED, FakeMachine
from rosutil import RosProcess, init_ros, shutdown_ros
from test_supervisor_node import START, ZONES

SUPERVISOR = "lhd_loading_ros.nodes.supervisor_node"


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    init_ros()
    node = rclpy.create_node("test_supervisor_commands")
    r = FakeMachine(node, START)
    r.pub_active = node.create_publisher(String, "/lhd/cmd_mux/active", LATCHED)
    r.run_dir = tmp_path_factory.mktemp("run_commands")
    r.proc = RosProcess(SUPERVISOR, {"run_dir": str(r.run_dir), "attempt_timeout": 5.0, "arm_delay": 0.2},
                        r.run_dir.parent / "supervisor_commands.log")
    r.pub_slope.publish(Float64(data=math.radians(20.0)))
    r.pub_zones.publish(Float64MultiArray(data=ZONES))
    yield r
    r.proc.stop()
    r.close()
    node.destroy_node()
    shutdown_ros()


def run_attempt(rig, n):
    rig.pub_active.publish(String(data="none"))
    n0 = len(rig.statuses)
    res = rig.call(rig.arm_client)
    assert res.success, res.message
    rig.wait_state("running", n, since=n0)
    return n0


def test_the_controllers_source_timing_out_ends_the_attempt(rig):
    rig.wait_state("idle", 0, timeout=60)
    time.sleep(0.3)
    n0 = run_attempt(rig, 1)
    rig.pub_active.publish(String(data="auto"))
    time.sleep(0.3)
    assert rig.state()["state"] == "running"
    rig.pub_active.publish(String(data="none"))
    _, kv = rig.wait_state("lost_input", 1, since=n0, timeout=5.0)
    assert kv["reason"].startswith("the controller's commands stopped: the command mux's auto source timed out"), kv


def test_the_gamepad_taking_over_aborts_the_attempt(rig):
    n0 = run_attempt(rig, 2)
    rig.pub_active.publish(String(data="auto"))
    time.sleep(0.3)
    rig.pub_active.publish(String(data="teleop"))
    _, kv = rig.wait_state("aborted", 2, since=n0, timeout=5.0)
    assert kv["reason"] == "the operator took over: the command mux selected 'teleop' over the controller", kv


def test_the_bridges_command_watchdog_ends_the_attempt(rig):
    n0 = run_attempt(rig, 3)
    rig.pub_active.publish(String(data="auto"))
    time.sleep(0.3)
    rig.command_stale = True
    try:
        _, kv = rig.wait_state("lost_input", 3, since=n0, timeout=5.0)
    finally:
        rig.command_stale = False
    assert kv["reason"].startswith("the bridge took no valid command for its cmd_timeout"), kv


def test_no_autonomous_attempt_is_armed_while_the_gamepad_drives(rig):
    """The deadman held at the arming: the mux has teleop selected, and an RLD attempt is refused
    (a review found a whole attempt driven by the gamepad recorded as RLD's)."""
    rig.pub_active.publish(String(data="teleop"))
    time.sleep(0.3)
    res = rig.call(rig.arm_client)
    assert not res.success and "the command mux has 'teleop' selected (the gamepad's deadman held?)" in res.message, \
        res.message
    rig.pub_active.publish(String(data="none"))
