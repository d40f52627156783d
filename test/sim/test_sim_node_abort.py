"""The sim node when MuJoCo finds its state unstable mid-episode (SimulationError): the episode ends
as `aborted` with the reason on /lhd/episode's status, nothing is stepped further from a machine
teleported back to its initial pose, no NaN is published, and (lockstep, auto_reset) the next
episode starts on the controller's answer to the aborted state (or after LOCKSTEP_ACK_WAIT_S). A real SimNode in this process over rclpy; the instability is a NaN velocity put
into its MuJoCo data, which mj_step detects and resets as it would a diverging state."""
import math

import numpy as np
import rclpy
from rclpy.parameter import Parameter

from rosutil import init_ros, shutdown_ros


def test_an_unstable_state_aborts_the_episode_and_the_next_one_starts():
    from lhd_sim_node.sim_node import SimNode
    init_ros()
    node = SimNode(parameter_overrides=[Parameter("mode", value="lockstep"), Parameter("auto_reset", value=True)])
    try:
        ep0 = node.episode
        node._on_cmd(type("M", (), {"data": [1.0, 0.0, 0.0]})())
        assert node.outcome == "running" and node.env.steps == 1
        node.sim.data.qvel[0] = math.nan
        node._on_cmd(type("M", (), {"data": [1.0, 0.0, 0.0]})())
        # ended as aborted; (lockstep + auto_reset) the controller's answer to that state starts the
        # next episode, without stepping it (it answered the aborted state, not the new one)
        assert node.episode == ep0 and node.outcome == "aborted" and "unstable" in node.abort_reason
        assert np.isfinite(node.sim.data.qvel).all() and np.isfinite(node._obs).all()
        node._on_cmd(type("M", (), {"data": [0.0, 0.0, 0.0]})())
        assert node.episode == ep0 + 1 and node.outcome == "running" and node.env.steps == 0
        # a controller that does not answer an ended state: the next episode after LOCKSTEP_ACK_WAIT_S
        from lhd_sim_node.sim_node import LOCKSTEP_ACK_WAIT_S
        node.sim.data.qvel[0] = math.nan
        node._on_cmd(type("M", (), {"data": [1.0, 0.0, 0.0]})())
        assert node.episode == ep0 + 1 and node.outcome == "aborted"
        node._repeat_state()
        assert node.episode == ep0 + 1                     # not yet: it waits for the answer
        node._ended_at -= LOCKSTEP_ACK_WAIT_S
        node._repeat_state()
        assert node.episode == ep0 + 2 and node.outcome == "running" and node.env.steps == 0
        node.auto_reset = False
        node.sim.data.qvel[0] = math.nan
        node._on_cmd(type("M", (), {"data": [1.0, 0.0, 0.0]})())
        st = {kv.key: kv.value for kv in node._status().values}
        assert node.outcome == "aborted" and st["state"] == "aborted" and "unstable" in st["reason"]
        assert all(math.isfinite(float(st[k])) for k in ("loaded_mass", "x_shovel", "z_shovel"))
        steps = node.env.steps
        node._on_cmd(type("M", (), {"data": [1.0, 0.0, 0.0]})())      # no stepping of an ended episode
        assert node.env.steps == steps
    finally:
        node.destroy_node()
        shutdown_ros()


def test_an_end_zone_reached_nearly_empty_is_said_to_be_no_success():
    """State `success` is the end in the end zone (the task's and the supervisor's term); the
    paper's success also needs 20 kg and a final pitch above 40 deg. Boom up and bucket curled from
    the first step reaches the end zone with about 2 kg (a review, 2026-11-28, saw `episode 0
    success: loaded 2.2 kg, SL 0` at level OK): the status's message and reason say it is no
    success, at WARN; the state stays `success`."""
    from diagnostic_msgs.msg import DiagnosticStatus

    from lhd_sim_node.sim_node import SimNode
    init_ros()
    node = SimNode(parameter_overrides=[Parameter("mode", value="lockstep"), Parameter("auto_reset", value=False),
                                        Parameter("slope_deg", value=20.0), Parameter("seed", value=3)])
    try:
        for _ in range(200):
            if node.outcome != "running":
                break
            node._on_cmd(type("M", (), {"data": [2.7, -0.191, 0.2]})())
        st = node._status()
        kv = {k.key: k.value for k in st.values}
        assert kv["state"] == "success" and kv["success"] == "False" and kv["success_level"] == "0", kv
        assert float(kv["loaded_mass"]) < 20.0
        assert st.level == DiagnosticStatus.WARN and "not a success: SL 0" in st.message, st.message
        assert kv["reason"].startswith("bucket tip reached the end zone; not a success: SL 0") and \
            "at least 20 kg and a final pitch above 40 deg" in kv["reason"], kv["reason"]
    finally:
        node.destroy_node()
        shutdown_ros()
