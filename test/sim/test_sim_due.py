"""The simulator as the Arduino Due (lhd_sim_node/sim_due.py): the firmware's rules by hand, the
sensor frame's conventions and motor currents by hand, advance() against step(), the device
watchdog over a real pty with a hand-written host, and the real bridge node (a separate process,
over DDS) on the device's pty: its /lhd/joint_states are the simulator's joints, its
/lhd/load_cell/mass the simulator's loaded mass."""
import math
import os
import re
import time
import tty
from pathlib import Path

import numpy as np
import pytest

from lhd_hw_bridge.protocol import (FLAG_ENABLED, FLAG_ESTOP, FLAG_HELD, FLAG_RESET, FLAG_WATCHDOG, TYPE_LOAD_CELL, TYPE_SENSOR,
                                    CommandFrame, FrameParser, HeartbeatFrame, LoadCellFrame, SensorFrame,
                                    TxSequence)
from lhd_sim_node import sim_due
from lhd_sim_node.sim_due import (Firmware, Outputs, Reading, SimDue, actuator_command, load_cell_frame,
                                  motor_currents, read_simulator, sensor_frame)
from lhd_sim_node.simulator import LhdSimulator

INO = Path(__file__).resolve().parents[2] / "lhd_hw_bridge/lhd_hw_bridge/firmware/lhd_due/lhd_due.ino"


def test_firmware_constants_are_the_reference_firmwares():
    src = INO.read_text()

    def const(name):
        return float(re.search(rf"\b{name}\s*=\s*(-?[0-9.]+)f?\s*[;,]", src).group(1))

    assert sim_due.WATCHDOG_S == const("WATCHDOG_MS") / 1000.0
    assert sim_due.WHEEL_MAX == const("WHEEL_MAX")
    assert (sim_due.BOOM_MIN, sim_due.BOOM_MAX) == (const("BOOM_MIN"), const("BOOM_MAX"))
    assert (sim_due.BUCKET_MIN, sim_due.BUCKET_MAX) == (const("BUCKET_MIN"), const("BUCKET_MAX"))
    assert sim_due.SENSOR_PERIOD == const("SENSOR_PERIOD_US") / 1e6
    assert "MAINTENANCE_BUILD = false" in src      # lowering / forward tilt refused, as the twin does


def test_firmware_clamps_refuses_and_closes_valves_at_the_limits():
    fw = Firmware()
    assert fw.outputs(0.0, 0.0) == Outputs(False, 0.0, 0, 0, False, False, True, True)  # no command yet: held
    fw.receive(CommandFrame(3.5, 1, 1, True), 0.0)
    assert fw.outputs(0.0, 0.0) == Outputs(False, 0.0, 0, 0, False, False, True, True)  # until a stop frame
    assert fw.outputs(0.0, 0.0).flags == FLAG_HELD | FLAG_RESET
    fw.receive(CommandFrame.stop(), 0.0)
    fw.receive(CommandFrame(3.5, 1, 1, True), 0.0)
    assert fw.outputs(-0.5, 0.5) == Outputs(True, 2.7, 1, 1, False, False)         # clamped to 2.7
    fw.receive(CommandFrame(-1.0, -1, -1, True), 0.01)
    assert fw.outputs(-0.5, 0.5) == Outputs(True, 0.0, 0, 0, False, False)         # no reverse, lower, tilt
    fw.receive(CommandFrame(1.0, 1, 1, True), 0.02)
    assert fw.outputs(-1.0, 1.4) == Outputs(True, 1.0, 0, 0, False, False)         # both at their limits
    assert fw.outputs(-0.999, 1.399) == Outputs(True, 1.0, 1, 1, False, False)
    fw.receive(CommandFrame(1.0, 1, 1, False), 0.03)                               # enable 0: all stopped
    assert fw.outputs(-0.5, 0.5) == Outputs(False, 0.0, 0, 0, False, False)
    assert Outputs(True, 1.0, 1, 0, False, False).flags == FLAG_ENABLED


def test_firmware_watchdog_and_estop():
    fw = Firmware(watchdog=0.25)
    fw.receive(CommandFrame.stop(), 0.0)        # the bridge's first frame clears the power-up hold
    fw.command, fw.last_cmd = None, None
    fw.check_watchdog(10.0)
    assert not fw.tripped                       # before the first command the watchdog is not armed
    fw.receive(CommandFrame(2.0, 1, 0, True), 0.0)
    fw.check_watchdog(0.25)
    assert not fw.tripped                       # "more than 250 ms"
    fw.check_watchdog(0.2501)
    out = fw.outputs(-0.5, 0.5)
    assert fw.tripped and fw.trips == 1 and out == Outputs(False, 0.0, 0, 0, False, True)
    assert out.flags == FLAG_WATCHDOG
    fw.receive(HeartbeatFrame(5), 0.3)          # a heartbeat does not re-arm the machine
    fw.check_watchdog(0.3)
    assert fw.outputs(-0.5, 0.5).watchdog
    fw.receive(CommandFrame(2.0, 1, 0, True), 0.4)   # a fresh command does
    assert fw.outputs(-0.5, 0.5) == Outputs(True, 2.0, 1, 0, False, False)
    fw.estop = True
    out = fw.outputs(-0.5, 0.5)
    assert out == Outputs(False, 0.0, 0, 0, True, False, True) and out.flags == FLAG_ESTOP | FLAG_HELD
    fw.estop = False                            # released: nothing restarts (ISO 13850), held
    assert fw.outputs(-0.5, 0.5) == Outputs(False, 0.0, 0, 0, False, False, True)
    fw.receive(CommandFrame(2.0, 1, 0, True), 0.5)   # not even the same command again
    assert fw.outputs(-0.5, 0.5).held
    fw.receive(CommandFrame.stop(), 0.6)        # a stop frame clears the hold; then commands run
    fw.receive(CommandFrame(2.0, 1, 0, True), 0.7)
    assert fw.outputs(-0.5, 0.5) == Outputs(True, 2.0, 1, 0, False, False)


def test_actuator_command_is_the_valve_times_the_full_speed(params):
    # the task's ranges: boom_min -0.191 rad/s (a lift), bucket_max 0.2 rad/s (a curl)
    u = actuator_command(Outputs(True, 1.3, 1, 1, False, False), abs(params.boom_min), params.bucket_max)
    assert u.tolist() == [1.3, -0.191, 0.2]
    u = actuator_command(Outputs(True, 2.7, 0, 1, False, False), 0.191, 0.2)
    assert u.tolist() == [2.7, 0.0, 0.2]
    assert actuator_command(sim_due.STOPPED, 0.191, 0.2).tolist() == [0.0, 0.0, 0.0]


def test_sensor_frame_signs_rear_differential_currents_and_saturation():
    r = Reading(boom=-0.31234, bucket=0.45678, boom_rate=-0.191, bucket_rate=0.2,
                wheels=(2.0, 2.2, 1.0, 3.0), torques=(10.0, -6.0, 12.0, 18.0))
    f = sensor_frame(r, Outputs(True, 2.0, 1, 1, False, False), 1_234_567)
    # angles and rates unchanged in sign, at the protocol's resolution (1e-4)
    assert f.boom_angle == pytest.approx(-0.3123) and f.bucket_angle == pytest.approx(0.4568)
    assert f.boom_rate == pytest.approx(-0.191) and f.bucket_rate == pytest.approx(0.2)
    assert (f.wheel_fl, f.wheel_fr) == (pytest.approx(2.0), pytest.approx(2.2))
    assert f.wheel_rear == pytest.approx(2.0)                   # (1.0 + 3.0) / 2: the differential's carrier
    # I = 1.5 A + |tau| / K: front 10 / 4 = 2.5 -> 4.0 A, 6 / 4 = 1.5 -> 3.0 A; rear (12 + 18) / 5 = 6 -> 7.5 A
    assert (f.current_fl, f.current_fr, f.current_rear) == (pytest.approx(4.0), pytest.approx(3.0),
                                                           pytest.approx(7.5))
    assert (f.valve_boom, f.valve_bucket, f.flags, f.device_time_us) == (1, 1, FLAG_ENABLED, 1_234_567)
    # a wheel at its torque limit (30 N m) reads above the bridge's no-drift presets (8 A / 12 A)
    front, _, rear = motor_currents((30.0, 0.0, 30.0, 30.0))
    assert front == pytest.approx(9.0) and rear == pytest.approx(13.5)
    # out-of-range values are sent at the field's limit (the firmware's sat16), never refused
    big = Reading(4.0, -4.0, 0.0, 0.0, (40.0, 0.0, 0.0, 0.0), (0.0, 0.0, 400.0, 0.0))
    f = sensor_frame(big, sim_due.STOPPED, 0)
    assert (f.boom_angle, f.bucket_angle, f.wheel_fl) == (pytest.approx(3.2767), pytest.approx(-3.2768),
                                                          pytest.approx(32.767))
    assert f.current_rear == pytest.approx(65.535)
    TxSequence().encode(f)                                      # encodable


def test_load_cell_frame_carries_the_mass_in_grams():
    f = load_cell_frame(12.3456, 7)
    # raw = round(150000 + 12.3456 x 85800) = round(1209252.48) = 1209252; mass = (1209252 - 150000) / 85800
    assert f.raw == 1_209_252
    assert f.mass == round(1_059_252 / 85_800, 3) == 12.346
    assert f.calibrated and f.tared and not f.saturated and not f.stale


def test_advance_is_step_in_20_ms_chunks(cfg):
    """Five advance() calls integrate the same model as one step(): after 2 s of driving, lifting
    and curling in the pile the two machines agree closely (not bit for bit: step refreshes the
    kinematics once per 0.1 s, advance every 20 ms)."""
    a, b = LhdSimulator(cfg), LhdSimulator(cfg)
    for s in (a, b):
        s.reset(np.random.default_rng(3), alpha=math.radians(20), material="homogeneous", d_attack=0.15,
                attack_speed=2.0)
    u = np.array([1.5, -0.191, 0.2])
    for _ in range(20):
        a.step(u)
        for _ in range(a.n_phys // a.fee_every):
            b.advance(u)
    sa, sb = a.state(), b.state()
    assert a.fee_dt == pytest.approx(0.02)
    assert sa.phi_boom == pytest.approx(sb.phi_boom, abs=2e-3) and sa.phi_boom < -0.3
    assert sa.phi_bucket == pytest.approx(sb.phi_bucket, abs=2e-3) and sa.phi_bucket > 0.3
    assert sa.x_shovel == pytest.approx(sb.x_shovel, abs=5e-3)
    assert a.loaded_mass == pytest.approx(b.loaded_mass, rel=0.05, abs=0.05) and a.loaded_mass > 0.5


@pytest.fixture
def sim(cfg):
    s = LhdSimulator(cfg)
    s.reset(np.random.default_rng(5), alpha=math.radians(25), material="homogeneous", d_attack=0.15, attack_speed=2.0)
    return s


def test_sensors_sample_the_machine_between_chunks(sim):
    """A chunk simulates its 20 ms at once; a sensor sampling at a wall instant inside the chunk
    sees the state interpolated between the chunk's start and end (checked against the two
    states read off the simulator), not the end state up to 20 ms early."""
    due = SimDue(sim)
    due.firmware.receive(CommandFrame.stop(), 0.0)        # the host's first frame: the power-up hold cleared
    due.firmware.receive(CommandFrame(2.7, 0, 0, True), 0.0)
    for k in range(10):                        # get the machine moving
        due.step_chunk(0.02 * k, 100.0 + 0.02 * k)
    p0, q0, v0 = sim.data.qpos[:3].copy(), sim.data.qpos[3:7].copy(), float(sim.data.qvel[0])
    due.step_chunk(0.2, 100.2)
    p1, q1, v1 = sim.data.qpos[:3].copy(), sim.data.qpos[3:7].copy(), float(sim.data.qvel[0])
    assert p1[0] - p0[0] > 1e-3                                    # it moved during the chunk
    for t, a in ((100.2, 0.0), (100.205, 0.25), (100.21, 0.5), (100.22, 1.0), (100.5, 1.0), (99.0, 0.0)):
        p, q, v, t_state = due.base_state_at(t)
        assert t_state == pytest.approx(min(t, 100.22))           # late: the state of the chunk's end
        assert p == pytest.approx((1 - a) * p0 + a * p1, abs=1e-12)
        assert v == pytest.approx((1 - a) * v0 + a * v1, abs=1e-12)
        assert np.linalg.norm(q) == pytest.approx(1.0)
        assert q == pytest.approx((1 - a) * q0 + a * q1, abs=1e-6)   # nlerp over a few mrad
    due.skip_backlog()                                             # a new pile: the current state
    p, q, v, t_state = due.base_state_at(100.21)
    assert p == pytest.approx(p1) and v == pytest.approx(v1) and t_state == 100.21


def test_a_device_whose_arm_sensors_are_zeroed_off_the_attack_pose(sim):
    """SimDue.arm_zero_error (the twin's arm_zero_error_deg): the device's frames carry the true angles plus
    the error (at the protocol's 1e-4 rad), its rates untouched, and its own joint limits act on what its
    sensors read, as the firmware's do on the machine: a bucket whose sensor reads past BUCKET_MAX gets its
    curl valve closed while the true angle is well inside the range."""
    due = SimDue(sim)
    due.firmware.receive(CommandFrame.stop(), 0.0)        # the host's first frame: the power-up hold cleared
    due.firmware.receive(CommandFrame(0.0, 0, 1, True), 0.0)              # curl back
    due.step_chunk(0.0, 100.0)
    assert due.applied.valve_bucket == 1                                   # inside the limits: it curls
    true = sim.state()
    f0 = due.sensor_frame_now(100.02)
    due.arm_zero_error = (0.02, sim_due.BUCKET_MAX - true.phi_bucket + 0.01)
    f1 = due.sensor_frame_now(100.02)
    assert f1.boom_angle - f0.boom_angle == pytest.approx(0.02, abs=1.1e-4)
    assert f1.bucket_angle == pytest.approx(sim_due.BUCKET_MAX + 0.01, abs=1.1e-4)
    assert (f1.boom_rate, f1.bucket_rate) == (f0.boom_rate, f0.bucket_rate)
    due.firmware.receive(CommandFrame(0.0, 0, 1, True), 0.02)
    due.step_chunk(0.02, 100.02)
    assert due.applied.valve_bucket == 0 and sim.state().phi_bucket < sim_due.BUCKET_MAX - 0.5   # the device's limit


def test_the_devices_rates_are_the_firmwares_differences_over_its_window(sim):
    """The frames' boom and bucket rates are what the firmware computes (arm_rate.h): the difference of the
    angles the frames carry over the last 0.1 s, so after the valves open they ramp up over 0.1 s and then read
    the joints' speeds; a new pile (skip_backlog) starts the window afresh."""
    due = SimDue(sim)
    due.firmware.receive(CommandFrame.stop(), 0.0)        # the host's first frame: the power-up hold cleared
    frames, t = [], 100.0
    for k in range(20):
        due.firmware.receive(CommandFrame(0.0, 1, 1, True), 0.02 * k)      # lift and curl at full speed
        due.step_chunk(0.02 * k, t)
        frames.append((t + 0.01, due.sensor_frame_now(t + 0.01)))          # two frames a chunk, at 100 Hz
        frames.append((t + 0.02, due.sensor_frame_now(t + 0.02)))
        t += 0.02
    for i, (ti, f) in enumerate(frames):
        back = [(tj, g) for tj, g in frames[:i] if ti - tj >= 0.1 - 1e-9]
        tj, g = back[-1] if back else frames[0]
        want = 0.0 if tj == ti else (f.boom_angle - g.boom_angle) / (ti - tj)
        # the firmware differentiates its own angles; the frames carry them in 1e-4 rad steps
        tol = 1e-4 + (0.0 if tj == ti else 1e-4 / (ti - tj))
        assert f.boom_rate == pytest.approx(want, abs=tol), i
    s = sim.state()
    assert s.dphi_boom < -0.15 and frames[-1][1].boom_rate == pytest.approx(s.dphi_boom, abs=3e-3)
    assert s.dphi_bucket > 0.15 and frames[-1][1].bucket_rate == pytest.approx(s.dphi_bucket, abs=3e-3)
    assert abs(frames[1][1].boom_rate) < 0.5 * abs(frames[-1][1].boom_rate)   # 20 ms after the valve: ramping
    # a new pile puts the arm back in the attack pose: without the reset the window would read the jump
    boom_q = sim.boom_q
    with due.lock:
        sim.data.qpos[boom_q] += 0.3
    assert due.sensor_frame_now(t + 0.03).boom_rate > 2.0                       # 0.3 rad in 0.11 s, no reset
    with due.lock:
        sim.data.qpos[boom_q] -= 0.6
        due.skip_backlog()
    assert due.sensor_frame_now(t + 0.04).boom_rate == 0.0                      # one sample: no rate yet


def _host(link):
    fd = os.open(link, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    return fd


def _read(fd, parser, out):
    try:
        out += [m for _, m in parser.feed(os.read(fd, 65536))]
    except BlockingIOError:
        pass


def test_device_watchdog_over_the_pty(sim, tmp_path):
    """A host that sends command frames and then falls silent: the machine drives, then the
    device stops it 250 ms after the last frame (flag bit 1), and the next frame re-arms it."""
    due = SimDue(sim, link=str(tmp_path / "due")).start()
    fd = _host(due.link)
    tx, parser, frames = TxSequence(), FrameParser(accept={TYPE_SENSOR, TYPE_LOAD_CELL}), []
    try:
        os.write(fd, tx.encode(CommandFrame.stop()))     # a host's first frame, as the bridge's: clears the hold
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            os.write(fd, tx.encode(CommandFrame(1.0, 0, 0, True)))
            time.sleep(0.02)
            _read(fd, parser, frames)
        t_last = time.monotonic()
        os.write(fd, tx.encode(CommandFrame(1.0, 0, 0, True)))
        sensors = [f for f in frames if isinstance(f, SensorFrame)]
        assert sensors[-1].flags == FLAG_ENABLED and sensors[-1].wheel_fl > 0.3     # driving (into the pile)
        t_trip = None
        while time.monotonic() < t_last + 1.0:
            time.sleep(0.005)
            n = len(frames)
            _read(fd, parser, frames)
            if t_trip is None and any(isinstance(f, SensorFrame) and f.flags & FLAG_WATCHDOG for f in frames[n:]):
                t_trip = time.monotonic()
        assert t_trip is not None, "the device watchdog never tripped"
        # 250 ms, then up to one 20 ms chunk until the outputs change, one 10 ms frame period,
        # and scheduling on a busy machine
        assert 0.25 <= t_trip - t_last <= 0.25 + 0.2
        assert due.firmware.trips == 1
        last = [f for f in frames if isinstance(f, SensorFrame)][-1]
        assert last.flags == FLAG_WATCHDOG and (last.valve_boom, last.valve_bucket) == (0, 0)
        assert abs(sim.state().v_x) < 0.02 and abs(last.wheel_fl) < 0.1      # braked to a stop
        # load-cell frames at 10 Hz beside the sensor frames at 100 Hz, no sequence gaps
        n_lc = sum(isinstance(f, LoadCellFrame) for f in frames)
        n_s = sum(isinstance(f, SensorFrame) for f in frames)
        assert 7 <= n_s / n_lc <= 13 and parser.seq_gaps == 0 and parser.crc_errors == 0
        os.write(fd, tx.encode(CommandFrame(1.0, 0, 0, True)))          # re-armed by a fresh command
        time.sleep(0.1)
        frames.clear()
        _read(fd, parser, frames)
        assert [f for f in frames if isinstance(f, SensorFrame)][-1].flags == FLAG_ENABLED
    finally:
        os.close(fd)
        due.stop()
    assert due.stats.chunks > 50 and due.sim_time == pytest.approx(due.stats.chunks * 0.02)


# ------------------------------------------------------------------ the real bridge on the device
rclpy = pytest.importorskip("rclpy")


@pytest.fixture(scope="module")
def ros():
    from rosutil import init_ros, shutdown_ros
    init_ros()
    yield
    shutdown_ros()


def test_bridge_joint_states_and_load_cell_are_the_simulators(ros, sim, tmp_path):
    """The bridge node (a separate process) on the device's pty. Through /lhd/cmd the arm lifts
    and curls; every /lhd/joint_states it publishes is one of the simulator's states at the
    protocol's resolution (angles 1e-4, wheels 1e-3; both rear wheels the differential's mean), with the
    protocol's signs: the boom angle falls (lifted), the bucket angle rises (curled); its rates are the
    firmware's, differences over 0.1 s (task/arm_sensors.py): at the steady lift the simulator's joint
    speeds, 0 once the arm has held for longer than the window. /lhd/load_cell/mass is the simulator's
    loaded mass to the gram."""
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64, Float64MultiArray

    from rosutil import RosProcess, spin_until

    truth = []

    def record(due):
        truth.append(read_simulator(due.sim))

    due = SimDue(sim, link=str(tmp_path / "due"), on_chunk=record).start()
    bridge = RosProcess("lhd_hw_bridge.bridge_node", {"port": due.link}, tmp_path / "bridge.log")
    node = rclpy.create_node("sim_due_test")
    js, mass = [], []
    node.create_subscription(JointState, "/lhd/joint_states", js.append, 200)
    node.create_subscription(Float64, "/lhd/load_cell/mass", lambda m: mass.append(m.data), 10)
    pub = node.create_publisher(Float64MultiArray, "/lhd/cmd", 1)
    try:
        assert spin_until(node, lambda: len(js) > 5 and mass, timeout=20.0), "no data from the bridge:\n" + bridge.log()
        with due.lock:
            m0 = sim.loaded_mass
        assert m0 > 0.0                                   # the attack cut some material
        assert mass[-1] == pytest.approx(m0, abs=1e-3)
        js.clear()
        for _ in range(3):                                # the fresh start the bridge waits for: an all-zero command
            pub.publish(Float64MultiArray(data=[0.0, 0.0, 0.0]))
            spin_until(node, lambda: False, timeout=0.05)
        t_end = time.monotonic() + 1.5
        while time.monotonic() < t_end:                   # drive, lift and curl at full speed
            pub.publish(Float64MultiArray(data=[1.0, -0.191, 0.2]))
            spin_until(node, lambda: False, timeout=0.05)
        spin_until(node, lambda: False, timeout=0.6)      # the bridge's 0.3 s timeout stops the arm
        moving = [m for m in js if m.velocity[0] < -0.1]
        assert len(moving) > 40, f"{len(moving)} joint states with the boom lifting:\n" + bridge.log()
        assert js[-1].position[0] < -0.2 and js[-1].position[1] > 0.2     # lifted, curled
        assert list(js[-1].name[:2]) == ["boom", "bucket"]
        with due.lock:
            hist = list(truth[-400:])
        for m in js:
            b, k, _, _, fl, fr, rl, rr = (*m.position[:2], *m.velocity)
            match = [r for r in hist if abs(r.boom - b) <= 0.6e-4 and abs(r.bucket - k) <= 0.6e-4
                     and abs(r.wheels[0] - fl) <= 0.6e-3 and abs(r.wheels[1] - fr) <= 0.6e-3
                     and abs(0.5 * (r.wheels[2] + r.wheels[3]) - rl) <= 0.6e-3 and rl == rr]
            assert match, f"joint state {list(m.position[:2])} {list(m.velocity)} is none of the simulator's"
        steady = [r.boom_rate for r in hist if r.boom_rate < -0.1]
        assert np.median([m.velocity[0] for m in moving[10:-10]]) == pytest.approx(np.median(steady), abs=5e-3)
        assert abs(js[-1].velocity[0]) < 5e-3 and abs(js[-1].velocity[1]) < 5e-3     # held 0.6 s: no rate
        with due.lock:
            s = sim.state()
        # the arm stopped: the last joint state is where the simulator holds it, within the frame's
        # 1e-4 rad encoder step and the loaded arm's creep since that frame (a CI run saw 1.1e-4)
        assert js[-1].position[0] == pytest.approx(s.phi_boom, abs=3e-4)
        assert js[-1].position[1] == pytest.approx(s.phi_bucket, abs=3e-4)
        mass.clear()
        assert spin_until(node, lambda: len(mass) >= 2, timeout=5.0)
        with due.lock:
            m1 = sim.loaded_mass
        assert mass[-1] == pytest.approx(m1, abs=1e-3)
    finally:
        node.destroy_node()
        rc = bridge.stop()
        due.stop()
    assert rc == 0, bridge.log()


def test_noise_on_the_devices_angles_and_what_its_window_makes_of_it(sim):
    """SimDue.arm_angle_noise (the twin's arm_angle_noise_deg): each frame's angles carry fresh noise of that sd, and
    the rates the firmware's differences of the noisy angles: sqrt(2) sd / window, over the 0.1 s window and over
    one 10 ms frame (rate_window 0.01, the firmware before), 1,000 frames of a machine at rest."""
    sd = math.radians(0.3)
    for window in (0.1, 0.01):
        due = SimDue(sim, arm_angle_noise=sd, rate_window=window, noise_seed=3)
        true = sim.state()
        frames = [due.sensor_frame_now(200.0 + 0.01 * k) for k in range(1000)]
        angles = np.array([f.boom_angle for f in frames]) - true.phi_boom
        rates = np.array([f.bucket_rate for f in frames[20:]])
        assert np.std(angles) == pytest.approx(sd, rel=0.1) and abs(np.mean(angles)) < 0.15 * sd
        assert np.std(rates) == pytest.approx(math.sqrt(2) * sd / window, rel=0.1), window
    with pytest.raises(ValueError, match="arm_angle_noise"):
        SimDue(sim, arm_angle_noise=-1.0)
