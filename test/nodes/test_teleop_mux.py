"""Teleop node + command mux + hardware bridge as real processes over DDS, the bridge on the
device emulator's pseudo-terminal. A synthetic Joy stream (an Xbox pad as joy_node publishes it:
8 axes, 11 buttons, triggers +1 released) stands in for the gamepad; the test also plays the
attempt supervisor (<prefix>/episode) and the autonomous controller (<prefix>/cmd/auto).

The latencies asserted are the requirements (300 ms; joy_timeout 0.5 s), measured on this
process's monotonic clock from the moment the test published the event to the moment the zero
command reached the test's /lhd/cmd subscriber or the stop frame reached the emulator."""
import math
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import Joy
from std_msgs.msg import Bool, Float64MultiArray, String

from lhd_hw_bridge.fake_due import FakeDue
from lhd_loading_ros.ros.qos import COMMAND_QOS, LATCHED_QOS, STATUS_QOS

from rosutil import RosProcess, init_ros, readline_past_middleware, shutdown_ros

ZERO = (0.0, 0.0, 0.0)
FULL = (2.7, 0.0, 0.0)                  # RT fully pressed: 2.7 rad/s (xbox.yaml, task range)
HALF = 0.45 / 0.95 * 2.7                # RT half pressed: p = 0.5 beyond the 0.05 deadzone
AUTO = [2.0, -0.191, 0.2]
LB, B, START = 4, 1, 7
LATENCY = {}                            # measured figures, printed at the end of the module


class Rig:
    def __init__(self, tmp):
        self.dev = FakeDue(link=str(tmp / "due"), rate=100.0, watchdog=0.25).start()
        self.procs = {
            "teleop": RosProcess("lhd_loading_ros.nodes.teleop_node", {}, tmp / "teleop.log"),
            "mux": RosProcess("lhd_loading_ros.nodes.cmd_mux_node", {}, tmp / "mux.log"),
            "bridge": RosProcess("lhd_hw_bridge.bridge_node", {"port": str(tmp / "due")}, tmp / "bridge.log"),
            # a second mux in its own namespace that never hears an attempt state
            "fresh": RosProcess("lhd_loading_ros.nodes.cmd_mux_node", {}, tmp / "fresh.log", remaps={"__ns": "/fresh"}),
        }
        n = self.node = rclpy.create_node("teleop_mux_test")
        self.ex = SingleThreadedExecutor()
        self.ex.add_node(n)
        self.got = {k: [] for k in ("cmd", "teleop", "fresh_cmd", "estop", "diag")}
        self.active = {"/lhd": None, "/fresh": None}
        stamp = lambda key: (lambda m: self.got[key].append((time.monotonic(), tuple(m.data))))
        n.create_subscription(Float64MultiArray, "/lhd/cmd", stamp("cmd"), 100)
        n.create_subscription(Float64MultiArray, "/lhd/cmd/teleop", stamp("teleop"), 100)
        n.create_subscription(Float64MultiArray, "/fresh/cmd", stamp("fresh_cmd"), 100)
        n.create_subscription(Bool, "/lhd/estop", lambda m: self.got["estop"].append((time.monotonic(), m.data)),
                              LATCHED_QOS)
        for ns in self.active:
            n.create_subscription(String, f"{ns}/cmd_mux/active",
                                  lambda m, ns=ns: self.active.__setitem__(ns, m.data), LATCHED_QOS)
        n.create_subscription(DiagnosticArray, "/diagnostics", lambda m: self.got["diag"].append(m), 50)
        self.pub_joy = n.create_publisher(Joy, "/joy", 10)           # as joy_node: reliable, depth 10
        self.pub_auto = n.create_publisher(Float64MultiArray, "/lhd/cmd/auto", COMMAND_QOS)
        self.pub_fresh_auto = n.create_publisher(Float64MultiArray, "/fresh/cmd/auto", COMMAND_QOS)
        self.pub_episode = n.create_publisher(DiagnosticStatus, "/lhd/episode", STATUS_QOS)
        self.attempt = 0
        self.status, self.status_t = None, 0.0   # repeated every 0.25 s, as the supervisor (2 Hz or more)

    def logs(self) -> str:
        return "\n".join(f"--- {k} (alive {p.alive()}):\n{p.log()[-2500:]}" for k, p in self.procs.items())

    def spin(self, seconds: float) -> None:
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            self._repeat_status()
            self.ex.spin_once(timeout_sec=min(0.005, max(t_end - time.monotonic(), 0.0)))

    def _repeat_status(self) -> None:
        if self.status is not None and time.monotonic() - self.status_t > 0.25:
            self.pub_episode.publish(self.status)
            self.status_t = time.monotonic()

    def wait(self, pred, timeout: float) -> bool:
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            self._repeat_status()
            self.ex.spin_once(timeout_sec=0.01)
            if pred():
                return True
        return pred()

    def joy(self, deadman=False, rt=1.0, pressed=(), axes=None, buttons=None) -> float:
        msg = Joy()
        if axes is None:
            axes = [0.0, 0.0, 1.0, 0.0, 0.0, rt, 0.0, 0.0]
        if buttons is None:
            buttons = [0] * 11
            for b in ((LB,) if deadman else ()) + tuple(pressed):
                buttons[b] = 1
        msg.axes, msg.buttons = [float(a) for a in axes], buttons
        self.pub_joy.publish(msg)
        return time.monotonic()

    def stream(self, seconds: float, rate: float = 20.0, auto=None, fresh_auto=None, **joy) -> float:
        """Joy (if any keyword given or joy=True) and auto commands at `rate` Hz; returns the
        time of the last publish."""
        t_end = time.monotonic() + seconds
        last = time.monotonic()
        while time.monotonic() < t_end:
            if joy:
                last = self.joy(**joy)
            if auto is not None:
                self.pub_auto.publish(Float64MultiArray(data=list(auto)))
            if fresh_auto is not None:
                self.pub_fresh_auto.publish(Float64MultiArray(data=list(fresh_auto)))
            self.spin(1.0 / rate)
        return last

    def episode(self, state: str) -> float:
        if state == "running":
            self.attempt += 1
        st = DiagnosticStatus(name="lhd attempt", message=state)
        st.values = [KeyValue(key="state", value=state), KeyValue(key="episode", value=str(max(self.attempt, 1)))]
        self.pub_episode.publish(st)
        self.status, self.status_t = st, time.monotonic()
        return time.monotonic()

    def after(self, key: str, t: float) -> list:
        return [(ts, c) for ts, c in self.got[key] if ts > t]

    def frames_after(self, t: float) -> list:
        return [(ts, f) for ts, f in self.dev.last_commands() if ts > t]

    def diag(self, name: str):
        """The newest status of that name on /diagnostics ('<node's full name>: <what>')."""
        for arr in reversed(self.got["diag"]):
            for s in arr.status:
                if s.name == name:
                    return s
        return None

    def reset(self) -> None:
        """Attempt idle, e-stop released, deadman released, every source silent: nothing selected."""
        self.episode("idle")
        # released as `lhd estop off` does it: a latched publisher that goes away afterwards (a
        # lasting one would keep offering its stale value to later subscribers)
        pub = self.node.create_publisher(Bool, "/lhd/estop", LATCHED_QOS)
        pub.publish(Bool(data=False))
        self.stream(0.45, deadman=False)         # > the sources' 0.3 s: nothing fresh, nothing cut
        assert self.wait(lambda: self.active["/lhd"] == "none", 2.0), (self.active, self.logs())
        self.node.destroy_publisher(pub)


def stop_after(cmds: list, t_event: float) -> float:
    """Seconds from the event to the first zero command after it; nothing but zeros after that
    zero. A command the sender published before the event (another topic: DDS orders nothing
    across topics) may still arrive in between, and only before the zero."""
    zeros = [t for t, c in cmds if c == ZERO]
    assert zeros, cmds
    assert all(c == ZERO for t, c in cmds if t >= zeros[0]), cmds
    assert all(t - t_event < 0.1 for t, c in cmds if t < zeros[0]), cmds
    return zeros[0] - t_event


def moving(frame) -> bool:
    return frame.wheel_setpoint > 0.0 or frame.valve_boom != 0 or frame.valve_bucket != 0


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    init_ros()
    r = Rig(tmp_path_factory.mktemp("teleop_mux"))
    try:
        ready = lambda: (r.active["/lhd"] == "none" and r.active["/fresh"] == "none"
                         and r.node.count_subscribers("/joy") >= 1 and r.node.count_publishers("/lhd/cmd/teleop") >= 1
                         and len(r.dev.last_commands()) > 5 and r.got["cmd"])
        assert r.wait(ready, 40.0), (r.active, r.logs())
        yield r
    finally:
        codes = {k: p.stop() for k, p in r.procs.items()}
        r.ex.remove_node(r.node)
        r.node.destroy_node()
        r.dev.stop()
        shutdown_ros()
        print("\nmeasured stop latencies (s):", {k: round(v, 3) for k, v in LATENCY.items()})
    assert codes == {k: 0 for k in codes}, (codes, r.logs())


def test_auto_commands_need_a_running_attempt_and_stop_at_its_end(rig):
    # (1) no /episode publisher at all (the /fresh mux never heard one): only zeros, at 10 Hz
    t0 = time.monotonic()
    rig.stream(0.8, fresh_auto=AUTO)
    out = rig.after("fresh_cmd", t0)
    assert out and all(c == ZERO for _, c in out), out
    assert 6 <= len(out) <= 11, len(out)                       # idle zeros at idle_rate_hz = 10
    # /diagnostics comes once a second (later on a loaded machine): keep the auto stream going
    # until a report written during it has arrived, rather than take whatever came so far
    gated = lambda: (s := rig.diag("/fresh/lhd_cmd_mux: selection")) is not None and \
        "auto: gated: attempt state is unknown" in s.message  # noqa: E731
    t_end = time.monotonic() + 6.0
    while not gated() and time.monotonic() < t_end:
        rig.stream(0.3, fresh_auto=AUTO)
    assert gated(), rig.diag("/fresh/lhd_cmd_mux: selection")
    # (2) state idle: only zeros reach /lhd/cmd and nothing moves at the emulator
    rig.reset()
    t1 = rig.episode("idle")
    rig.stream(0.5, auto=AUTO)
    assert all(c == ZERO for _, c in rig.after("cmd", t1))
    assert not any(moving(f) for _, f in rig.frames_after(t1))
    # (3) running: forwarded at once, the emulator's valves open and its wheels turn
    t2 = rig.episode("running")
    rig.stream(0.5, auto=AUTO)
    assert (2.0, -0.191, 0.2) in [c for _, c in rig.after("cmd", t2)], rig.logs()
    assert rig.active["/lhd"] == "auto"
    f = rig.dev.last_commands()[-1][1]
    assert f.wheel_setpoint == pytest.approx(2.0, abs=0.01) and f.valve_boom == 1 and f.valve_bucket == 1
    # (4) the attempt ends while the controller keeps talking: a zero within 300 ms, then nothing else
    t3 = rig.episode("success")
    rig.stream(0.6, auto=AUTO)
    LATENCY["auto_attempt_end_to_zero"] = stop_after(rig.after("cmd", t3), t3)
    assert LATENCY["auto_attempt_end_to_zero"] < 0.3
    frames = rig.frames_after(t3)
    t_stop = next(t for t, fr in frames if not moving(fr))
    LATENCY["auto_attempt_end_to_stop_frame"] = t_stop - t3
    assert t_stop - t3 < 0.3 and not any(moving(fr) for t, fr in frames if t > t_stop)


def test_teleop_drives_the_emulator_and_releasing_the_deadman_stops_it(rig):
    rig.reset()
    t0 = time.monotonic()
    rig.stream(0.3, deadman=False, rt=1.0)                     # released, trigger at rest
    rig.stream(1.0, deadman=True, rt=-1.0)                     # deadman held, full throttle
    assert FULL in [c for _, c in rig.after("cmd", t0)], rig.logs()
    assert rig.active["/lhd"] == "teleop"
    driving = [f for _, f in rig.frames_after(t0) if f.wheel_setpoint > 0.0]
    assert driving and driving[-1].wheel_setpoint == pytest.approx(2.7, abs=0.01)
    assert rig.dev.plant.wheel_fl > 2.0                        # the emulated wheels follow (0.1 s lag)
    t_rel = rig.joy(deadman=False, rt=-1.0)                    # let go of LB, thumb still on RT
    rig.stream(0.8, deadman=False, rt=-1.0)
    LATENCY["teleop_release_to_zero"] = stop_after(rig.after("cmd", t_rel), t_rel)
    assert LATENCY["teleop_release_to_zero"] < 0.3
    assert [c for _, c in rig.after("teleop", t_rel)] == [ZERO]   # one zero from teleop, then silence
    frames = rig.frames_after(t_rel)
    t_stop = next(t for t, fr in frames if fr.wheel_setpoint == 0.0 and not moving(fr))
    LATENCY["teleop_release_to_stop_frame"] = t_stop - t_rel
    assert t_stop - t_rel < 0.3 and not any(moving(fr) for t, fr in frames if t > t_stop)


def test_joy_messages_stopping_stop_the_machine(rig):
    rig.reset()
    rig.stream(0.2, deadman=False)
    t_last = rig.stream(0.5, deadman=True, rt=-1.0)            # then the controller dies
    rig.spin(1.0)
    cmd = rig.after("cmd", t_last)
    zeros = [t for t, c in cmd if c == ZERO]
    assert zeros and all(c == ZERO or t < zeros[0] for t, c in cmd), cmd
    LATENCY["joy_lost_to_zero_on_cmd"] = zeros[0] - t_last    # the mux's 0.3 s source timeout comes first
    assert zeros[0] - t_last < 0.5 + 0.15
    tele = [(t, c) for t, c in rig.after("teleop", t_last) if c == ZERO]
    assert len(tele) == 1, rig.after("teleop", t_last)         # the teleop node's own stop: one zero
    LATENCY["joy_lost_to_teleop_zero"] = tele[0][0] - t_last
    assert 0.5 <= tele[0][0] - t_last < 0.5 + 0.15             # joy_timeout + its 20 ms check + delivery
    assert not any(moving(f) for t, f in rig.frames_after(zeros[0] + 0.05))
    assert rig.wait(lambda: (lambda d: d is not None and "no Joy message for" in d.message)(
        rig.diag("/lhd_teleop: joystick")), 1.5), rig.diag("/lhd_teleop: joystick")     # 1 Hz diagnostics


def test_estop_button_stops_within_300_ms_and_holds_until_the_release_combination(rig):
    rig.reset()
    rig.episode("running")
    rig.stream(0.2, deadman=False, auto=AUTO)
    rig.stream(0.5, deadman=True, rt=-1.0, auto=AUTO)          # teleop overrides auto
    assert rig.active["/lhd"] == "teleop"
    t_e = rig.joy(deadman=True, rt=-1.0, pressed=(B,))
    assert rig.wait(lambda: any(v for t, v in rig.got["estop"] if t > t_e), 1.0), rig.logs()
    LATENCY["estop_button_to_estop_topic"] = next(t for t, v in rig.got["estop"] if t > t_e and v) - t_e
    # the operator keeps the throttle down and the controller keeps talking: nothing moves
    rig.stream(0.7, deadman=True, rt=-1.0, auto=AUTO)
    LATENCY["estop_button_to_zero"] = stop_after(rig.after("cmd", t_e), t_e)
    assert LATENCY["estop_button_to_zero"] < 0.3
    assert rig.active["/lhd"] == "estop"
    frames = rig.frames_after(t_e)
    t_stop = next(t for t, fr in frames if not moving(fr))
    LATENCY["estop_button_to_stop_frame"] = t_stop - t_e
    assert t_stop - t_e < 0.3 and not any(moving(fr) for t, fr in frames if t > t_stop)
    # LB + START held 1 s releases it; the deadman held through the release does not drive
    t_r = rig.stream(1.3, rate=20.0, deadman=True, rt=1.0, pressed=(START,))
    assert rig.wait(lambda: rig.got["estop"][-1][1] is False and rig.active["/lhd"] != "estop", 1.0), rig.got["estop"]
    rig.stream(0.5, deadman=True, rt=-1.0)
    assert all(c == ZERO for _, c in rig.after("cmd", t_r)), rig.after("cmd", t_r)
    # released and pressed anew: drives again
    rig.stream(0.4, deadman=False)
    t_p = time.monotonic()
    rig.stream(0.4, deadman=True, rt=-1.0)
    assert FULL in [c for _, c in rig.after("cmd", t_p)]
    rig.episode("idle")


def test_teleop_overrides_auto_while_held_and_the_attempt_end_cuts_it_too(rig):
    rig.reset()
    rig.episode("running")
    t0 = time.monotonic()
    rig.stream(0.5, deadman=False, rt=1.0, auto=[1.0, 0.0, 0.0])
    assert (1.0, 0.0, 0.0) in [c for _, c in rig.after("cmd", t0)] and rig.active["/lhd"] == "auto"
    t1 = time.monotonic()
    rig.stream(0.6, deadman=True, rt=0.0, auto=[1.0, 0.0, 0.0])     # half throttle, deadman held
    cmd = rig.after("cmd", t1)
    first = next(i for i, (_, c) in enumerate(cmd) if c[0] == pytest.approx(HALF))
    assert all(c[0] == pytest.approx(HALF) for _, c in cmd[first:]), cmd     # auto overridden
    assert rig.active["/lhd"] == "teleop"
    t2 = rig.joy(deadman=False, rt=0.0)
    rig.stream(0.8, deadman=False, rt=0.0, auto=[1.0, 0.0, 0.0])
    cmd = rig.after("cmd", t2)
    assert cmd[0][1] == ZERO                                   # teleop's release zero
    back = [t for t, c in cmd if c == (1.0, 0.0, 0.0)]
    assert back and back[0] - t2 > 0.3 - 0.05, cmd             # auto again once teleop timed out
    assert rig.active["/lhd"] == "auto"
    # teleop held again (fresh press) when the attempt ends: stopped and cut, not gated afterwards
    t3 = time.monotonic()
    rig.stream(0.4, deadman=True, rt=-1.0, auto=[1.0, 0.0, 0.0])
    assert FULL in [c for _, c in rig.after("cmd", t3)]
    t_end = rig.episode("failure")
    rig.stream(0.6, deadman=True, rt=-1.0, auto=[1.0, 0.0, 0.0])
    LATENCY["teleop_attempt_end_to_zero"] = stop_after(rig.after("cmd", t_end), t_end)
    assert LATENCY["teleop_attempt_end_to_zero"] < 0.3
    rig.stream(0.4, deadman=False)                             # release: silent > 0.3 s
    t4 = time.monotonic()
    rig.stream(0.4, deadman=True, rt=-1.0)                     # repositioning between attempts
    assert FULL in [c for _, c in rig.after("cmd", t4)]


def test_bad_commands_and_malformed_joy(rig):
    rig.reset()
    rig.episode("running")
    t0 = time.monotonic()
    rig.stream(0.3, auto=[5.0, 0.5, -1.0])                     # out of range: clamped
    rig.stream(0.3, auto=[math.nan, 0.0, 0.0])                 # not a number: rejected
    cmd = rig.after("cmd", t0)
    assert (2.7, 0.0, 0.0) in [c for _, c in cmd]
    assert not any(any(math.isnan(v) for v in c) for _, c in cmd)
    assert rig.wait(lambda: (lambda s: s is not None and int({k.key: k.value for k in s.values}["auto_rejected"]) >= 3)
                    (rig.diag("/lhd_cmd_mux: sources")), 2.5), rig.diag("/lhd_cmd_mux: sources")
    sel = rig.diag("/lhd_cmd_mux: selection")
    assert "non-finite wheels" in sel.message, sel.message
    rig.episode("idle")
    # a Joy message with too few axes while the operator drives: a zero, then ignored
    rig.stream(0.4, deadman=False)
    t_last = rig.stream(0.3, deadman=True, rt=-1.0)
    # the drive stream's last command arrives before the bad message is stamped (on a loaded 2-core machine it
    # came after it once, CI 2026-11-30); well inside the 0.5 s joy_timeout, which would send a zero of its own
    rig.wait(lambda: any(ts > t_last for ts, _ in rig.got["teleop"]), 0.3)
    t_bad = rig.joy(axes=[0.0, 0.0, 1.0, 0.0], buttons=[0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0])
    rig.stream(0.5, axes=[0.0, 0.0, 1.0, 0.0], buttons=[0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0])
    assert [c for _, c in rig.after("teleop", t_bad)] == [ZERO]
    assert rig.wait(lambda: (lambda s: s is not None and "Joy has 4 axes" in s.message)(rig.diag("/lhd_teleop: joystick")),
                    2.5), rig.diag("/lhd_teleop: joystick")
    t_ok = time.monotonic()
    rig.stream(0.4, deadman=True, rt=-1.0)                     # valid again, deadman still held
    assert not rig.after("teleop", t_ok)                       # needs a fresh press


def test_estop_from_a_volatile_publisher_is_obeyed_and_mirrored_by_the_teleop_node(rig):
    """`ros2 topic pub /lhd/estop std_msgs/Bool '{data: true}'` publishes reliable volatile: the mux
    and the teleop node hear it all the same, and the teleop node's latched copy tells a late
    subscriber (a restarted mux or supervisor) that the e-stop is engaged."""
    rig.reset()
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    pub = rig.node.create_publisher(Bool, "/lhd/estop", QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    try:
        # volatile: matched by the volatile subscriptions of the mux and the teleop node only
        assert rig.wait(lambda: pub.get_subscription_count() >= 2, 10.0), pub.get_subscription_count()
        t0 = time.monotonic()
        pub.publish(Bool(data=True))
        assert rig.wait(lambda: rig.active["/lhd"] == "estop", 2.0)
        late = []
        sub = rig.node.create_subscription(Bool, "/lhd/estop", lambda m: late.append(m.data), LATCHED_QOS)
        # the teleop node's latched copy says engaged (a released value may come too, from a
        # latched writer of an earlier test whose removal this new subscription has not yet seen)
        assert rig.wait(lambda: True in late, 5.0), (late, rig.got["estop"])
        rig.node.destroy_subscription(sub)
        assert rig.after("estop", t0)[0][1] is True
        pub.publish(Bool(data=False))
        assert rig.wait(lambda: rig.active["/lhd"] == "none" and rig.got["estop"][-1][1] is False, 2.0)
    finally:
        rig.node.destroy_publisher(pub)


def test_estop_samples_queued_in_a_stall_settle_on_the_newest_without_an_echo_loop(rig):
    """Samples that reach the teleop node while it is stalled (here: engage, release, engage from a
    latched publisher like `lhd estop`'s, which then leaves) come out of its two subscriptions in
    either order, and its own mirror publications come back to it. Until 2026-11-28 it mirrored
    whatever differed from its last publication, its own older echoes included: 12,000-15,000
    messages in 8 s after the sender left, the value flipping until teardown and the mux left on
    `none` (a review's fault injection). Now: a few messages, and the newest, engaged, holds."""
    import os
    import signal

    from rclpy.duration import Duration

    rig.reset()
    teleop = rig.procs["teleop"].proc
    pub = rig.node.create_publisher(Bool, "/lhd/estop", LATCHED_QOS)
    assert rig.wait(lambda: pub.get_subscription_count() >= 4, 10.0), pub.get_subscription_count()
    os.killpg(teleop.pid, signal.SIGSTOP)
    try:
        for v in (True, False, True):             # the newest: engaged
            pub.publish(Bool(data=v))
            rig.spin(0.005)
        rig.spin(0.3)
    finally:
        os.killpg(teleop.pid, signal.SIGCONT)
    pub.wait_for_all_acked(Duration(seconds=1.0))
    rig.node.destroy_publisher(pub)
    t0 = time.monotonic()
    rig.spin(3.0)
    heard = rig.after("estop", t0)
    assert len(heard) <= 6, (len(heard), heard[:10], heard[-10:])
    assert rig.got["estop"][-1][1] is True and rig.active["/lhd"] == "estop", (heard[-10:], rig.active)


def test_estop_cli_engages_and_releases_through_the_mux(rig):
    rig.reset()

    def cli(*args):
        # the default --timeout, 10 s (3 s until 2026-11-28 was sometimes shorter than a new
        # process's DDS discovery on this loaded 2-core machine)
        return subprocess.run([sys.executable, "-m", "lhd_loading_ros.cli.estop", *args], capture_output=True,
                              text=True, timeout=30)

    r = cli("on")
    assert r.returncode == 0 and "ENGAGED" in r.stdout and "confirms (active: estop)" in r.stdout, (r.stdout, r.stderr)
    assert rig.wait(lambda: rig.active["/lhd"] == "estop", 1.0)
    r = cli("status")
    assert r.returncode == 0 and "/lhd/cmd_mux/active: estop" in r.stdout and "/lhd/estop: " in r.stdout, r
    rig.stream(0.4, deadman=False)
    t1 = time.monotonic()
    rig.stream(0.4, deadman=True, rt=-1.0)
    assert all(c == ZERO for _, c in rig.after("cmd", t1))
    r = cli("off")
    assert r.returncode == 0 and "released" in r.stdout, (r.stdout, r.stderr)
    assert rig.wait(lambda: rig.active["/lhd"] == "none", 1.0)
    r = cli("on", "--namespace", "/nowhere", "--timeout", "0.5")
    assert r.returncode == 1 and "no confirmation from the command mux" in r.stderr and "may NOT be in effect" in r.stderr, r
    assert cli("on", "--timeout", "0").returncode == 2


def test_bad_mapping_or_sources_end_the_nodes_with_one_line_and_exit_2(tmp_path):
    (tmp_path / "pad.yaml").write_text("name: pad\ndeadman_button: 4\nestop_button: 4\nestop_release_buttons: [7]\n"
                                       "wheels: [{axis: 5}]\n")
    (tmp_path / "mux.yaml").write_text("sources: [{name: a, topic: x, priority: 1, timeout: 0.3, gated: maybe}]\n")
    procs = {
        "no such mapping": (RosProcess("lhd_loading_ros.nodes.teleop_node", {"mapping": "bogus"}, tmp_path / "t1.log"),
                            "parameter 'mapping' = 'bogus' is neither a shipped mapping ('xbox', 'ps4', 'f710', "
                            "'game_controller') nor a readable file"),
        "bad mapping": (RosProcess("lhd_loading_ros.nodes.teleop_node", {"mapping": str(tmp_path / "pad.yaml")},
                                   tmp_path / "t2.log"), "deadman_button and estop_button are both 4"),
        "bad sources": (RosProcess("lhd_loading_ros.nodes.cmd_mux_node", {"sources_file": str(tmp_path / "mux.yaml")},
                                   tmp_path / "m.log"), "sources[0].gated = 'maybe'; expected true"),
    }
    for what, (p, needle) in procs.items():
        assert p.proc.wait(30) == 2, (what, p.log())
        log = p.log()
        assert needle in log and "Traceback" not in log, (what, log)




def test_a_killed_supervisor_ends_the_attempt_in_the_mux(rig, tmp_path):
    """The supervisor's process is killed mid-attempt (SIGKILL: no DDS goodbye, so the graph still
    lists its publisher for the ~20 s of its lease): its last status says running. Within
    status_timeout (1.5 s) plus a tick the mux sends a zero and forwards no more auto commands,
    though the controller keeps sending them; before the fix it forwarded them for as long as it
    was watched. Measured from the kill."""
    import os
    import signal

    rig.reset()
    rig.status = None                              # the stand-in process is the supervisor now
    script = Path(__file__).with_name("stand_in_supervisor.py")
    sup = subprocess.Popen([sys.executable, str(script), "77"], start_new_session=True,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert readline_past_middleware(sup.stdout).strip() == "publishing"
        t0 = time.monotonic()
        while not any(c == tuple(AUTO) for _, c in rig.after("cmd", t0)):   # until the mux has heard it
            assert time.monotonic() - t0 < 20.0, rig.logs()
            rig.stream(0.2, auto=AUTO)
        rig.stream(1.0, auto=AUTO)
        os.killpg(sup.pid, signal.SIGKILL)
        sup.wait()
        t_kill = time.monotonic()
        rig.stream(3.0, auto=AUTO)
        after = rig.after("cmd", t_kill)
        zero_at = next(t for t, c in after if c == ZERO) - t_kill
        last_auto = max((t - t_kill for t, c in after if c == tuple(AUTO)), default=0.0)
        assert 1.0 < zero_at <= 2.0, (zero_at, after, rig.logs())
        assert last_auto <= zero_at, (last_auto, zero_at)
        assert rig.active["/lhd"] == "none"
        assert "status lost" in rig.procs["mux"].log() and "status_timeout 1.5 s" in rig.procs["mux"].log()
        LATENCY["supervisor killed: mux zero after (s)"] = zero_at
    finally:
        if sup.poll() is None:
            os.killpg(sup.pid, signal.SIGKILL)
            sup.wait()
