"""Sim node and policy node as real processes over DDS: topics, reset service, stale-command
braking, zero commands on doubt, and parity with the in-process environment (lockstep)."""
import math
import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float32MultiArray, Float64, Float64MultiArray
from std_srvs.srv import Trigger

from lhd_loading_ros.policy.actor_file import load_policy
from lhd_loading_ros.nodes.policy_node import default_policy_dir

from rosutil import RosProcess, init_ros, shutdown_ros, spin_until

OBS_ATOL = 1e-6     # node observation vs environment observation (float32; FK vs MuJoCo sites agree to 1e-14 m)
MASS_ATOL = 1e-3    # kg, loaded mass of the same episode through the nodes and in process
REL = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
STATUS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL)


@pytest.fixture(scope="module")
def ros():
    init_ros()
    import rclpy

    node = rclpy.create_node("test_sim_policy")
    yield node
    node.destroy_node()
    shutdown_ros()


def kv(msg):
    return {k.key: k.value for k in msg.values}


def test_sim_node_rejects_bad_parameters(tmp_path):
    for params, name in (({"mode": "fast"}, "mode"), ({"slope_deg": 45.0}, "slope_deg"),
                         ({"material": "sand"}, "material"), ({"slopes_deg": "15,x"}, "slopes_deg"),
                         ({"exit_when_done": "true"}, "exit_when_done")):    # with episodes 0: never
        p = RosProcess("lhd_sim_node.sim_node", params, tmp_path / f"{name}.log")
        assert p.proc.wait(60) == 2
        assert f"parameter '{name}'" in p.log()
        p.stop()


def test_nodes_accept_their_ros_parameter_files(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import threading
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    for module, name in (("lhd_sim_node.sim_node", "sim_node"), ("lhd_loading_ros.nodes.policy_node", "policy_node")):
        p = subprocess.Popen([sys.executable, "-m", module, "--ros-args", "--params-file",
                              str(root / "config" / f"{name}.yaml")], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, start_new_session=True,
                             env=dict(os.environ, PYTHONUNBUFFERED="1", RCUTILS_LOGGING_BUFFERED_STREAM="0"))
        lines = []     # read in a thread: a node that prints less than expected must not hang the test
        reader = threading.Thread(target=lambda: lines.extend(iter(p.stdout.readline, "")), daemon=True)
        reader.start()
        try:
            t_end = time.monotonic() + 60
            while not any("sim node up: mode realtime" in x or "loaded RLD actor" in x for x in lines):
                assert time.monotonic() < t_end and p.poll() is None, lines
                time.sleep(0.1)
        finally:
            os.killpg(p.pid, signal.SIGINT)
            assert p.wait(20) == 0


def test_sim_node_topics_reset_and_stale_command_brake(ros, tmp_path):
    sim = RosProcess("lhd_sim_node.sim_node", {"mode": "realtime", "slope_deg": 20.0, "seed": 5}, tmp_path / "sim.log")
    got = {}
    js_log = []
    ros.create_subscription(JointState, "/lhd/joint_states", lambda m: js_log.append((time.monotonic(), m)), REL)
    for topic, typ in (("/lhd/odom", Odometry), ("/lhd/pile/slope", Float64), ("/lhd/wheel_drift", Bool),
                       ("/lhd/wheel_drift/front", Bool), ("/lhd/wheel_drift/rear", Bool),
                       ("/lhd/pile/end_zone", Float64MultiArray)):
        ros.create_subscription(typ, topic, lambda m, t=topic: got.__setitem__(t, m), REL)
    statuses = []
    ros.create_subscription(DiagnosticStatus, "/lhd/episode", lambda m: statuses.append(kv(m)), STATUS)
    pub = ros.create_publisher(Float64MultiArray, "/lhd/cmd", REL)
    try:
        assert spin_until(ros, lambda: len(got) == 6 and js_log and statuses, 60), sim.log()
        assert got["/lhd/pile/slope"].data == pytest.approx(math.radians(20.0))
        js = js_log[-1][1]
        assert list(js.name)[:3] == ["boom", "bucket", "articulation"]
        assert got["/lhd/odom"].header.frame_id == "pile" and got["/lhd/odom"].child_frame_id == "base_link"
        x_min, x_max, z_min = got["/lhd/pile/end_zone"].data
        assert 0 < x_min < x_max and z_min == pytest.approx(0.35)
        assert statuses[-1]["state"] == "running" and statuses[-1]["episode"] == "0"
        # drive at full wheel speed for 1 s, then go silent: the wheels must brake after 0.3 s
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            pub.publish(Float64MultiArray(data=[2.7, 0.0, 0.0]))
            spin_until(ros, lambda: False, 0.05)
        t_last = time.monotonic()
        assert got["/lhd/odom"].twist.twist.linear.x > 0.1
        spin_until(ros, lambda: False, 1.2)
        wheel_v = [(t - t_last, abs(np.mean(m.velocity[3:]))) for t, m in js_log if t > t_last]
        assert any(v > 1.0 for dt, v in wheel_v if dt < 0.25), wheel_v      # still driving within the timeout
        assert all(v < 0.3 for dt, v in wheel_v if dt > 0.8), wheel_v       # braked after it
        assert "wheels braked" in sim.log()
        cli = ros.create_client(Trigger, "/lhd_sim/reset")
        assert cli.wait_for_service(timeout_sec=10)
        fut = cli.call_async(Trigger.Request())
        assert spin_until(ros, lambda: fut.done(), 10) and fut.result().success
        assert spin_until(ros, lambda: statuses[-1]["episode"] == "1", 10)
    finally:
        assert sim.stop() == 0


def test_policy_node_zero_command_without_actor_or_inputs(ros, tmp_path):
    cmds = []
    ros.create_subscription(Float64MultiArray, "/lhd/cmd", lambda m: cmds.append(list(m.data)), REL)
    # an attempt runs (the policy node commands only then), but there is no actor, or no input
    status = ros.create_publisher(DiagnosticStatus, "/lhd/episode", STATUS)
    status.publish(DiagnosticStatus(message="running", values=[KeyValue(key="state", value="running"),
                                                               KeyValue(key="episode", value="1")]))
    # the status is sent once: no age limit on it (status_timeout 0; the rule is test_policy_gating's)
    pol = RosProcess("lhd_loading_ros.nodes.policy_node", {"policy_dir": str(tmp_path / "missing"), "status_timeout": 0.0},
                     tmp_path / "p1.log")
    try:
        assert spin_until(ros, lambda: len(cmds) >= 5, 60), pol.log()
        assert all(c == [0.0, 0.0, 0.0] for c in cmds)
        assert "no actor" in pol.log()
    finally:
        rc = pol.stop()
        assert rc == 0, pol.log()
    cmds.clear()
    pol = RosProcess("lhd_loading_ros.nodes.policy_node", {"status_timeout": 0.0}, tmp_path / "p2.log")   # shipped actor, no inputs
    try:
        assert spin_until(ros, lambda: len(cmds) >= 5, 60), pol.log()
        assert all(c == [0.0, 0.0, 0.0] for c in cmds)
        assert "zero command: no joints received yet" in pol.log()
    finally:
        rc = pol.stop()
        ros.destroy_publisher(status)
        assert rc == 0, pol.log()


def test_policy_node_sends_a_last_zero_command_when_stopped(ros, tmp_path):
    """Stopped mid-episode (SIGINT from Ctrl-C, SIGTERM from a supervisor), the policy node's
    last word is the zero command, and it exits 0: the machine is not left on its last command."""
    import os
    import signal

    cmds = []
    sub = ros.create_subscription(Float64MultiArray, "/lhd/cmd", lambda m: cmds.append(list(m.data)), REL)
    sim = RosProcess("lhd_sim_node.sim_node", {"mode": "realtime", "slope_deg": 20.0, "seed": 3}, tmp_path / "sim.log")
    try:
        for i, sig in enumerate((signal.SIGINT, signal.SIGTERM)):
            cmds.clear()
            pol = RosProcess("lhd_loading_ros.nodes.policy_node", {}, tmp_path / f"pol{i}.log")
            try:
                assert spin_until(ros, lambda: any(c != [0.0, 0.0, 0.0] for c in cmds), 60), pol.log() + sim.log()
            finally:
                os.killpg(pol.proc.pid, sig)
                assert pol.proc.wait(10) == 0, pol.log()
                pol.stop()
            spin_until(ros, lambda: False, 0.5)
            assert cmds[-1] == [0.0, 0.0, 0.0], cmds[-5:]
            assert "stopping: sent a zero command" in pol.log()
    finally:
        assert sim.stop() == 0
        ros.destroy_subscription(sub)


def env_episode(env, pol, seed, slope, material):
    """One in-process episode of the actor: the observations it acted on, and the result."""
    obs, _ = env.reset(seed=seed, options={"slope_deg": slope, "material": material})
    seen = [obs]
    while True:
        obs, _, term, trunc, info = env.step(np.clip(pol.actor(obs), -1, 1))
        if term or trunc:
            return seen, info["episode_result"]
        seen.append(obs)


def run_lockstep_episode(ros, tmp_path, policy_dir, slope, material, seed, episodes=1, exit_when_done=False):
    """`episodes` episodes in lockstep (more than one: auto_reset, as `lhd demo` runs them); the
    policy node's observations of all of them in order, and the last /lhd/episode status. With
    exit_when_done the sim node must exit by itself, status 0, within a few seconds of the last end
    (what ends `ros2 launch lhd_sim_node sim_loading.launch.py episodes:=N`)."""
    obs_log, statuses = [], []
    subs = [ros.create_subscription(Float32MultiArray, "/lhd/observation", lambda m: obs_log.append(np.array(m.data, dtype=np.float32)), REL),
            ros.create_subscription(DiagnosticStatus, "/lhd/episode", lambda m: statuses.append(kv(m)), STATUS)]
    pol = RosProcess("lhd_loading_ros.nodes.policy_node", {"policy_dir": str(policy_dir), "trigger": "lockstep",
                                                     "input_qos": "reliable"}, tmp_path / "pol.log")
    # the policy's /lhd/observation must be matched before the first state exists (volatile topic)
    assert spin_until(ros, lambda: ros.count_publishers("/lhd/observation") >= 1, 60), pol.log()
    spin_until(ros, lambda: False, 0.5)
    sim = RosProcess("lhd_sim_node.sim_node", {"mode": "lockstep", "slope_deg": slope, "material": material,
                                               "seed": seed, "episodes": episodes,
                                               "auto_reset": "true" if episodes > 1 else "false",
                                               "exit_when_done": "true" if exit_when_done else "false"},
                     tmp_path / "sim.log")
    try:
        assert spin_until(ros, lambda: statuses and statuses[-1]["state"] != "running"
                          and statuses[-1]["episode"] == str(episodes - 1), 120), sim.log() + pol.log()
        if exit_when_done:
            # it exits by itself (EXIT_DELAY_S after the end, seen by a 0.5 s timer), not at once: the last
            # ended state was out and its status stays the last one published
            ended = time.monotonic()
            assert spin_until(ros, lambda: not sim.alive(), 15), sim.log()[-2000:]
            assert time.monotonic() - ended > 0.3, "exited before the last ended state had been out a while"
            assert sim.proc.returncode == 0 and "done: exiting (exit_when_done)" in sim.log(), sim.log()[-2000:]
        spin_until(ros, lambda: False, 0.5)
    finally:
        rc_pol, rc_sim = pol.stop(), sim.stop()
        assert rc_pol == 0 and rc_sim == 0, (rc_pol, rc_sim, pol.log()[-2000:], sim.log()[-2000:])
        for s in subs:
            ros.destroy_subscription(s)
    return obs_log, statuses[-1]


@pytest.mark.parallel_safe     # lockstep: the same observations whatever the load (test/conftest.py)
@pytest.mark.parametrize("variant,slope,material", [("rld", 25.0, "homogeneous"), ("rlc", 20.0, "nonhomogeneous")])
def test_lockstep_parity_with_the_environment(ros, tmp_path, variant, slope, material):
    from lhd_sim_node.env import LhdLoadingEnv

    policy_dir = default_policy_dir(variant)
    pol = load_policy(policy_dir)
    seed = 11
    env = LhdLoadingEnv(variant, deploy_filter=(variant == "rlc"))   # the node filters RLC only
    env_obs, ref = env_episode(env, pol, seed, slope, material)
    node_obs, final = run_lockstep_episode(ros, tmp_path, policy_dir, slope, material, seed)
    assert len(node_obs) == len(env_obs) == ref.steps
    errs = [float(np.abs(a - b).max()) for a, b in zip(node_obs, env_obs)]
    bad = [(k, np.flatnonzero(np.abs(node_obs[k] - env_obs[k]) > OBS_ATOL).tolist(), node_obs[k].tolist(), env_obs[k].tolist())
           for k, e in enumerate(errs) if e > OBS_ATOL]
    assert not bad, f"{len(bad)} of {len(errs)} observations differ; first (step, indices, node, env): {bad[0]}"
    assert final["state"] == ("success" if ref.reached_end_zone else ("failure" if ref.failed else "timeout"))
    assert (final["success"] == "True") == ref.success
    assert float(final["loaded_mass"]) == pytest.approx(ref.loaded, abs=MASS_ATOL)
    assert int(final["step"]) == ref.steps


@pytest.mark.parallel_safe     # lockstep: the same observations whatever the load (test/conftest.py)
def test_lockstep_auto_reset_runs_every_episode_as_the_environment(ros, tmp_path):
    """`lhd demo`'s lockstep with auto_reset: the second episode through the nodes sees exactly the
    environment's observations too. Until 2026-11-28 the policy node's answer to the first
    episode's ended state (its zero command) drove the second episode's first period, and every
    later command ran one period late: the second episode's observations differed from step 1 on
    (v_x -0.07 where the environment had 0.87, a drift flag), and an actor loaded 27 kg where it
    loads 37 in process."""
    from lhd_sim_node.env import LhdLoadingEnv

    policy_dir = default_policy_dir("rld")
    pol = load_policy(policy_dir)
    slope, material, seed = 15.0, "homogeneous", 5
    env = LhdLoadingEnv("rld")
    per_episode, refs = zip(*(env_episode(env, pol, seed + k, slope, material) for k in range(2)))
    # and the sim node exits by itself after the asked episodes (exit_when_done, as the launch file sets it)
    node_obs, final = run_lockstep_episode(ros, tmp_path, policy_dir, slope, material, seed, episodes=2,
                                           exit_when_done=True)
    n0 = refs[0].steps
    assert len(node_obs) == n0 + refs[1].steps, (len(node_obs), [r.steps for r in refs])
    for k, (node, ref) in enumerate(((node_obs[:n0], per_episode[0]), (node_obs[n0:], per_episode[1]))):
        bad = [t for t, (a, b) in enumerate(zip(node, ref)) if float(np.abs(a - b).max()) > OBS_ATOL]
        assert not bad, f"episode {k}: {len(bad)} of {len(ref)} observations differ, first at step {bad[0]}"
    assert final["episode"] == "1"
    assert float(final["loaded_mass"]) == pytest.approx(refs[1].loaded, abs=MASS_ATOL)
