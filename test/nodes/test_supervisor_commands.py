"""The supervisor node ends a running attempt whose commands stopped reaching the machine, as
real processes over DDS: the command mux's latched /lhd/cmd_mux/active leaving `auto` (the
controller stalled: lost_input; the gamepad took over: aborted) and the bridge's own command
watchdog in /lhd/hw/status (`command_stale`: the mux stalled). Before 2026-11-28 a controller or
mux stalled for 2 s drove on afterwards and the attempt was recorded as a success (a review's
fault injection on the twin). The rule itself: test/task/test_attempt.py."""
import time

import pytest
from std_msgs.msg import String

from fake_machine import LATCHED, close_rig, supervisor_rig
from test_supervisor_node import START, ZONES


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    r = supervisor_rig(tmp_path_factory, "test_supervisor_commands", {"attempt_timeout": 5.0, "arm_delay": 0.2},
                       START, zones=ZONES)
    r.pub_active = r.node.create_publisher(String, "/lhd/cmd_mux/active", LATCHED)
    yield r
    close_rig(r)


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
