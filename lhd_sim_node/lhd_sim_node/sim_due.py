"""The simulator as the LHD's Arduino Due: the device side of docs/serial_protocol.md on a
pseudo-terminal, with the MuJoCo machine (LhdSimulator) as the plant, stepped in real time.

ROS-free. The twin node (twin_node.py) runs one SimDue; a test can run one in-process.

What the device does, as the reference firmware (lhd_hw_bridge/firmware/lhd_due/lhd_due.ino,
`apply_outputs` and `loop`) and its emulator (lhd_hw_bridge/fake_due.py) do it:
* takes command (0x02) and heartbeat (0x03) frames; any other or broken frame is dropped and never
  changes the outputs (lhd_hw_bridge.protocol.FrameParser, the device's `accept`);
* watchdog: no valid command frame for 250 ms after a first one -> wheels to 0, valves closed,
  enable cleared, flag bit 1 set, until the next valid command frame;
* the wheel set-point is clamped to [0, 2.7] rad/s; boom lowering (-1) and bucket forward tilt
  (-1) are refused (not a maintenance build); a valve is closed at its joint limit
  (boom <= -1.0 rad raising, bucket >= 1.4 rad curling);
* while the emergency stop is pressed (`estop`): wheels 0, valves closed, flag bit 2; held (flag
  bit 3) and, from power-up, flagged reset (bit 5) until a stop frame (enable = 0): a release alone
  never restarts the machine. The simulator's readings are always readings, so this device never
  reports a sensor fault (bit 4; lhd_hw_bridge.fake_due can);
* sensor frames (0x01) at 100 Hz, load-cell frames (0x04) at 10 Hz (`load_cell`, default on).

The plant is the simulator, driven with the actuator command of the outputs (`actuator_command`):
wheels = the clamped set-point (rad/s; the simulator's wheel motors: one per front wheel, one for the rear differential), boom / bucket = the valve
state x the full hydraulic speed (TaskParams.boom_min: -0.191 rad/s, a lift; TaskParams.bucket_max:
+0.2 rad/s, a curl): the valves are ternary, the machine has no proportional arm speed; zero when
the drive is disabled, the watchdog holds or the e-stop is pressed. The machine is stepped in
chunks of one FEE period (LhdSimulator.advance, 20 ms), the command latched at the start of each
chunk, so a command frame reaches the machine within 20 ms of arrival.

Sensor frames are built from the simulator's state (`sensor_frame`). The conventions of
docs/serial_protocol.md and of the simulator's joints agree (mjcf.py: the boom hinge about +y,
negative lifts; the bucket hinge about -y, positive curls back; both 0 in the attack pose), so
boom_angle = phi_boom, bucket_angle = phi_bucket, unchanged in sign; their rates as the firmware computes
them (arm_rate.h): the difference of the angles the frames carry over the last 0.1 s
(task/arm_sensors.RateWindow), not the joints' velocities, so they lag a valve's opening by up to 0.1 s.
* wheel_fl / wheel_fr: the front wheels' joint speeds (rad/s, positive forward);
  wheel_rear: the mean of the two rear wheels: one motor drives them through a differential, whose
  carrier (the motor's shaft after the gearbox) turns at the mean of its two output shafts;
* motor currents from the actuator forces (the wheel servos' torques at the wheel, N m):
  I = I_IDLE + |tau| / K with K the motor's torque constant times its gear ratio, referred to
  the wheel: K_FRONT = 4.0 N m/A per front motor, K_REAR = 5.0 N m/A for the rear motor, which
  carries the torque of both rear wheels; I_IDLE = 1.5 A (the emulator's no-load current).
  Why these K: the bridge's drift presets (config hardware.drift_current_front 8 A, _rear 12 A)
  are "no-drift" limits, and a wheel drifts in the simulator when its servo saturates at the
  motor's torque limit (machine.wheel_torque_limit 30 N m) and the tyre slips. With these K the
  presets sit at 87.5 % of the saturated torque on both axles: front (8 - 1.5) x 4.0 = 26 N m of 30,
  rear (12 - 1.5) x 5.0 = 52.5 N m of 2 x 30, so a motor at its limit reads 9.0 A / 13.5 A (over
  the preset) and one pushing the pile below 87.5 % of it reads under the preset. The motor
  data sheet of the scaled machine is not public; these constants are the assumption, stated once;
* valve states: what the valves do (the latched outputs: closed on a limit, the e-stop, the
  watchdog), not an echo of the command; flags as the firmware's.
The load cell weighs the simulator's loaded mass (LhdSimulator.loaded_mass) through the emulated
amplifier (fake_due.LOAD_CELL_OFFSET / LOAD_CELL_SCALE: the same 24-bit counts and mass in grams
the firmware sends; calibrated and tared).
"""
from __future__ import annotations

import os
import select
import threading
import time
from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from lhd_hw_bridge.fake_due import LOAD_CELL_OFFSET, LOAD_CELL_SCALE
from lhd_hw_bridge.pty_link import close_pty, open_pty
from lhd_hw_bridge.protocol import (ANGLE_SCALE, CURRENT_SCALE, FLAG_ENABLED, FLAG_ESTOP, FLAG_HELD, FLAG_RESET,
                                    FLAG_WATCHDOG,
                                    LC_CALIBRATED, LC_SATURATED, LC_TARED, RATE_SCALE, RAW_MAX, RAW_MIN, TYPE_COMMAND,
                                    TYPE_HEARTBEAT, WHEEL_SCALE, CommandFrame, FrameParser, LoadCellFrame,
                                    SensorFrame, TxSequence)
from lhd_loading_ros.task.arm_sensors import RATE_WINDOW_S, RateWindow

# the firmware's constants (lhd_due.ino; test/sim/test_sim_due.py reads them from the file)
WATCHDOG_S = 0.250              # WATCHDOG_MS
WHEEL_MAX = 2.7                 # rad/s
BOOM_MIN, BOOM_MAX = -1.0, 0.05       # rad, joint limits
BUCKET_MIN, BUCKET_MAX = -0.1, 1.4    # rad
SENSOR_PERIOD = 0.010           # s, SENSOR_PERIOD_US (100 Hz)
LOAD_CELL_PERIOD = 0.100        # s (10 Hz)
# the motors (module docstring: why these values)
K_FRONT = 4.0                   # N m per A, each front wheel motor, referred to the wheel
K_REAR = 5.0                    # N m per A, the rear motor (both rear wheels through the differential)
I_IDLE = 1.5                    # A, no-load current of a motor
COMMAND_LOG = 10_000            # command frames kept in SimDue.command_log (200 s at 50 Hz)
CATCH_UP = 5                    # chunks the loop runs back to back when late; later than that it resynchronises


@dataclass(frozen=True)
class Outputs:
    """What the firmware drives (apply_outputs): the drive enabled, the wheel set-point, the
    valves' real states and the e-stop, with the watchdog flag of the moment."""
    run: bool
    wheel: float
    valve_boom: int
    valve_bucket: int
    estop: bool
    watchdog: bool
    held: bool = False
    was_reset: bool = False

    @property
    def flags(self) -> int:
        return (FLAG_ENABLED if self.run else 0) | (FLAG_WATCHDOG if self.watchdog else 0) | \
            (FLAG_ESTOP if self.estop else 0) | (FLAG_HELD if self.held else 0) | (FLAG_RESET if self.was_reset else 0)


STOPPED = Outputs(False, 0.0, 0, 0, False, False, True, True)


class Firmware:
    """The device's command handling (lhd_due.ino: handle_packet, the watchdog in loop(),
    apply_outputs), ROS-free and clock-agnostic: `now` is the caller's monotonic time in s."""

    def __init__(self, watchdog: float = WATCHDOG_S):
        self.watchdog = watchdog
        self.command: CommandFrame | None = None   # the last valid command frame
        self.last_cmd: float | None = None
        self.tripped = False
        self.trips = 0
        self.estop = False                         # the emergency-stop button, pressed
        self.held = True                           # stopped from power-up until a stop frame (enable = 0)
        self.was_reset = True                      # flag bit 5, likewise
        self.commands = 0
        self.heartbeats = 0

    def receive(self, msg, now: float) -> None:
        """A valid frame from the host (the parser dropped the bad ones)."""
        if isinstance(msg, CommandFrame):
            self.command = msg
            self.last_cmd = now
            self.tripped = False          # a fresh valid command re-arms the machine
            if not msg.enable and not self.estop:
                self.held = self.was_reset = False    # a stop frame clears the hold
            self.commands += 1
        else:
            self.heartbeats += 1          # host clock only: the command stream feeds the watchdog

    def check_watchdog(self, now: float) -> None:
        if self.command is not None and not self.tripped and now - self.last_cmd > self.watchdog:
            self.tripped = True
            self.trips += 1
            self.command = CommandFrame.stop()    # the firmware clears the command when it trips

    def outputs(self, boom_angle: float, bucket_angle: float) -> Outputs:
        c = self.command
        if self.estop:
            self.held = True
            self.command = CommandFrame.stop()     # the firmware forgets the command on an e-stop
            c = self.command
        run = c is not None and c.enable and not self.tripped and not self.estop and not self.held
        if not run:
            return Outputs(False, 0.0, 0, 0, self.estop, self.tripped, self.held, self.was_reset)
        wheel = min(max(c.wheel_setpoint, 0.0), WHEEL_MAX)
        boom = max(c.valve_boom, 0)        # lowering refused (not a maintenance build)
        bucket = max(c.valve_bucket, 0)    # forward tilt refused
        if boom > 0 and not boom_angle > BOOM_MIN:      # +1 raises: the angle decreases to its limit (NaN: closed)
            boom = 0
        if bucket > 0 and not bucket_angle < BUCKET_MAX:
            bucket = 0
        return Outputs(True, wheel, boom, bucket, False, False)


def actuator_command(out: Outputs, boom_speed: float, bucket_speed: float) -> np.ndarray:
    """The simulator's command (u_wheels, u_boom, u_bucket) rad/s for the outputs: a raising boom
    valve moves the boom at -boom_speed (negative lifts), a curling bucket valve at +bucket_speed."""
    return np.array([out.wheel, -boom_speed * out.valve_boom, bucket_speed * out.valve_bucket])


def _sat(v: float, scale: float, lo: int, hi: int) -> float:
    """The firmware's sat16 / satu16: a value beyond the field's range is sent at its limit."""
    return min(max(round(v / scale), lo), hi) * scale


def motor_currents(wheel_torques) -> tuple[float, float, float]:
    """(front left, front right, rear) A from the wheel torques (fl, fr, rl, rr) N m."""
    fl, fr, rl, rr = (abs(float(t)) for t in wheel_torques)
    return I_IDLE + fl / K_FRONT, I_IDLE + fr / K_FRONT, I_IDLE + (rl + rr) / K_REAR


@dataclass(frozen=True)
class Reading:
    """The simulator's quantities a sensor frame carries (SI units, the simulator's signs)."""
    boom: float
    bucket: float
    boom_rate: float
    bucket_rate: float
    wheels: tuple[float, float, float, float]        # fl, fr, rl, rr rad/s
    torques: tuple[float, float, float, float]       # fl, fr, rl, rr N m (the wheel servos' forces)


def sensor_frame(r: Reading, out: Outputs, device_time_us: int) -> SensorFrame:
    fl, fr, rl, rr = r.wheels
    cur = motor_currents(r.torques)
    a = lambda v: _sat(v, ANGLE_SCALE, -32768, 32767)     # noqa: E731
    w = lambda v: _sat(v, WHEEL_SCALE, -32768, 32767)     # noqa: E731
    i = lambda v: _sat(v, CURRENT_SCALE, 0, 65535)        # noqa: E731
    return SensorFrame(
        device_time_us=device_time_us & 0xFFFFFFFF, boom_angle=a(r.boom), bucket_angle=a(r.bucket),
        boom_rate=_sat(r.boom_rate, RATE_SCALE, -32768, 32767), bucket_rate=_sat(r.bucket_rate, RATE_SCALE, -32768, 32767),
        wheel_fl=w(fl), wheel_fr=w(fr), wheel_rear=w(0.5 * (rl + rr)),
        current_fl=i(cur[0]), current_fr=i(cur[1]), current_rear=i(cur[2]),
        valve_boom=out.valve_boom, valve_bucket=out.valve_bucket, flags=out.flags)


def load_cell_frame(mass: float, device_time_us: int) -> LoadCellFrame:
    """The firmware's frame for `mass` kg in the bucket: the amplifier's counts (offset + mass x
    scale, 24-bit), the calibrated, tared mass computed from them, in grams."""
    raw = min(max(round(LOAD_CELL_OFFSET + mass * LOAD_CELL_SCALE), RAW_MIN), RAW_MAX)
    flags = LC_CALIBRATED | LC_TARED | (LC_SATURATED if raw in (RAW_MIN, RAW_MAX) else 0)
    return LoadCellFrame(device_time_us & 0xFFFFFFFF, round((raw - LOAD_CELL_OFFSET) / LOAD_CELL_SCALE, 3), raw, flags)


def read_simulator(sim) -> Reading:
    """The sensor quantities of an LhdSimulator now (its `state()` and wheel servos)."""
    s = sim.state()
    d = sim.data
    # WHEELS order in the simulator: fl, fr, rl, rr for the dofs and the actuators
    wheels = tuple(float(v) for v in d.qvel[sim.wheel_dof])
    torques = sim.wheel_torques()
    return Reading(s.phi_boom, s.phi_bucket, s.dphi_boom, s.dphi_bucket, wheels, torques)


@dataclass
class LoopStats:
    chunks: int = 0                 # 20 ms chunks simulated
    overruns: int = 0               # chunks run more than one chunk period after they were due
    resyncs: int = 0                # times the loop fell CATCH_UP chunks behind and dropped the backlog
    dropped_s: float = 0.0          # simulated time given up by the resyncs
    busy_s: float = 0.0             # wall time spent stepping the simulator
    max_chunk_s: float = 0.0        # the longest chunk's stepping time
    sensor_frames: int = 0
    load_cell_frames: int = 0
    write_errors: int = 0


@dataclass
class SimDue:
    """The device: a pty (behind the symlink `link`), the firmware, and the simulator `sim` as the
    plant, in a real-time thread (`start` / `stop`). `lock` guards the simulator: whoever reads
    or resets it from another thread takes it (`with due.lock:`). `on_chunk(due)` (optional) is
    called after each chunk with the lock held (the twin's truth samples). `command_log`: the
    latest COMMAND_LOG valid command frames as the device read them off the line, (wall time s,
    monotonic time s, CommandFrame), appended by the loop thread (deque appends are atomic);
    the twin publishes them for `lhd bench twin`'s latency."""
    sim: object
    link: str | None = None
    watchdog: float = WATCHDOG_S
    rate: float = 1.0 / SENSOR_PERIOD
    load_cell: bool = True
    on_chunk: object = None
    # rad: the device's boom and bucket angles read this far off the true ones (a sensor zeroed off the attack
    # pose, docs/real_machine.md "Calibration" step 7); its frames and its own joint limits see them, as on the
    # machine, and the bridge's boom_zero / bucket_zero take them off again
    arm_zero_error: tuple = (0.0, 0.0)
    # rad: sd of the noise on each sample of the boom and bucket angles its frames carry (a potentiometer's
    # ADC; docs/real_machine.md Calibration step 8), and s, the firmware's rate window (arm_rate.h; 0.01, one
    # 10 ms frame, is the firmware before 2026-11-29). The noise is drawn from `noise_seed`
    arm_angle_noise: float = 0.0
    rate_window: float = RATE_WINDOW_S
    noise_seed: int = 0
    firmware: Firmware = field(init=False)

    def __post_init__(self):
        self.firmware = Firmware(self.watchdog)
        self.parser = FrameParser(accept={TYPE_COMMAND, TYPE_HEARTBEAT})
        self.lock = threading.RLock()
        self.stats = LoopStats()
        self.chunk = float(self.sim.fee_dt)
        p = self.sim.p
        self.boom_speed, self.bucket_speed = abs(p.boom_min), p.bucket_max
        self.applied = STOPPED          # the outputs latched for the running chunk
        self.u = np.zeros(3)            # the simulator command of the running chunk
        self.sim_time = 0.0             # s simulated by this device (all episodes)
        self._tx = TxSequence()
        self._skip = False
        self.loop_t0 = None
        self._master = self._slave = None
        self.path = None
        self._stop = threading.Event()
        self._thread = None
        self.command_log: deque = deque(maxlen=COMMAND_LOG)
        self.t0 = time.monotonic()      # the device clock's zero (micros() since power-up)
        self._span = None               # (t0, t1, state at t0, state at t1) of the last chunk
        # the firmware's rates: differences of the angles its frames carry over RATE_WINDOW_S (arm_rate.h)
        self._rates = (RateWindow(self.rate_window), RateWindow(self.rate_window))
        if not (np.isfinite(self.arm_angle_noise) and self.arm_angle_noise >= 0.0):
            raise ValueError(f"arm_angle_noise {self.arm_angle_noise!r} rad: expected a standard deviation >= 0")
        self._noise = np.random.default_rng([self.noise_seed, 146])   # its own stream of the twin's seed
        self._rate_at = None            # (monotonic s, (boom, bucket rate), (boom, bucket noise)) of the last frame

    # ------------------------------------------------------------------ pty
    def plug(self) -> str:
        self._master, self._slave, self.path = open_pty(self.link)
        self.parser.reset_link()
        return self.link or self.path

    def unplug(self) -> None:
        close_pty(self._master, self._slave)
        self._master = self._slave = None
        if self.link and os.path.islink(self.link) and os.readlink(self.link) == self.path:
            os.unlink(self.link)

    # ------------------------------------------------------------------ e-stop (the machine's button)
    @property
    def estop(self) -> bool:
        return self.firmware.estop

    @estop.setter
    def estop(self, pressed: bool) -> None:
        self.firmware.estop = bool(pressed)

    # ------------------------------------------------------------------ loop
    def start(self) -> "SimDue":
        if self._master is None:
            self.plug()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="sim-due", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.unplug()

    def device_us(self, now: float) -> int:
        return int((now - self.t0) * 1e6)

    def skip_backlog(self) -> None:
        """The simulator was replaced under the loop (a new pile: the caller held `lock` for
        it): the chunks due meanwhile are not simulated, and not counted as overruns; the loop
        goes on from now. The firmware's rate windows start afresh (the caller holds `lock`, which
        sensor_frame_now takes for them)."""
        self._skip = True
        self._span = None
        for w in self._rates:           # the arm is put back in the attack pose: no rate across the jump
            w.reset()
        self._rate_at = None

    def _base_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """base_link's position, orientation (w, x, y, z) and linear velocity, world frame (the
        free joint's qpos[:7] and qvel[:3])."""
        d = self.sim.data
        return d.qpos[:3].copy(), d.qpos[3:7].copy(), d.qvel[:3].copy()

    def base_state_at(self, now: float) -> tuple[np.ndarray, np.ndarray, float, float]:
        """base_link's position, orientation (w, x, y, z) and v_x at monotonic time `now`, and the
        monotonic instant that state belongs to.

        A chunk simulates its 20 ms as soon as it is due, so between two chunks the simulator
        holds the state of the chunk's END, up to 20 ms ahead of the wall clock. A sensor that
        samples the machine at `now` (the twin's camera, its ground truth) gets the state
        interpolated between the chunk's start and end states at `now`: linear in position and
        speed, normalised linear in the quaternion (rotations of a few mrad per chunk).
        Without it, a camera stamped `now` would show the machine 0-20 ms ahead (7 mm at
        0.37 m/s): stamp jitter that no speed estimator can tell from motion.

        When the simulation has fallen behind the wall clock (`now` past the chunk's end: the
        next chunk is late on a loaded machine), the newest state is the chunk's end and the
        instant returned is that end, not `now`: a sensor stamps its message with it (a frame
        that shows the machine as it was, delivered late), so pose and speed stay consistent
        over the stamps. Before the span's start (or with no span) the instant is `now`."""
        p, q, v, t = self.base_motion_at(now)
        return p, q, float(v[0]), t

    def base_motion_at(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """As base_state_at, with base_link's whole linear velocity (world frame, m/s) instead of
        v_x: what the twin's accelerometer differentiates."""
        with self.lock:
            span = self._span
            if span is None:
                p, q, v = self._base_state()
                return p, q, v, now
            t0, t1, (p0, q0, v0), (p1, q1, v1) = span
        a = min(1.0, max(0.0, (now - t0) / (t1 - t0)))
        if float(q0 @ q1) < 0.0:
            q1 = -q1
        q = (1.0 - a) * q0 + a * q1
        t = min(now, t1)
        return (1.0 - a) * p0 + a * p1, q / np.linalg.norm(q), (1.0 - a) * v0 + a * v1, t

    def step_chunk(self, now: float, due: float | None = None) -> bool:
        """One chunk: latch the firmware's outputs for the joints' angles now, advance the
        simulator 20 ms with their actuator command. `due`: the monotonic instant the chunk's
        20 ms begin at in the real-time schedule (default `now`). False (nothing stepped) right
        after skip_backlog."""
        with self.lock:
            if self._skip:
                self._skip = False
                self._span = None
                return False
            s = self.sim
            start = self._base_state()
            boom = float(s.data.qpos[s.boom_q]) + self.arm_zero_error[0]       # what the device's sensors read
            bucket = float(s.data.qpos[s.bucket_q]) + self.arm_zero_error[1]
            self.firmware.check_watchdog(now)
            self.applied = self.firmware.outputs(boom, bucket)
            self.u = actuator_command(self.applied, self.boom_speed, self.bucket_speed)
            t = time.perf_counter()
            s.advance(self.u)
            dt = time.perf_counter() - t
            t_start = now if due is None else due
            self._span = (t_start, t_start + self.chunk, start, self._base_state())
            self.sim_time += self.chunk
            st = self.stats
            st.chunks += 1
            st.busy_s += dt
            st.max_chunk_s = max(st.max_chunk_s, dt)
            if self.on_chunk is not None:
                self.on_chunk(self)
        return True

    def sensor_frame_now(self, now: float) -> SensorFrame:
        """The frame of the state now, with the outputs the running chunk applies."""
        with self.lock:                 # skip_backlog resets the windows under it, from the twin node's thread
            r = read_simulator(self.sim)
            out = self.applied
            e = self.arm_zero_error
            if e != (0.0, 0.0):
                r = replace(r, boom=r.boom + e[0], bucket=r.bucket + e[1])
            # the rates as the firmware computes them: over its window, from the angles it reads (a second frame
            # asked for the same instant carries the same rates)
            if self._rate_at is None or now > self._rate_at[0]:
                nb, nk = (float(v) for v in self._noise.normal(0.0, self.arm_angle_noise, 2)) \
                    if self.arm_angle_noise > 0.0 else (0.0, 0.0)     # this frame's samples of the angles
                self._rate_at = (now, (self._rates[0].push(now, r.boom + nb), self._rates[1].push(now, r.bucket + nk)),
                                 (nb, nk))
            _, (rb, rk), (nb, nk) = self._rate_at
            r = replace(r, boom=r.boom + nb, bucket=r.bucket + nk, boom_rate=rb, bucket_rate=rk)
        return sensor_frame(r, out, self.device_us(now))

    def lag(self, now: float) -> float:
        """s of wall time since the loop started not simulated (late chunks and given-up backlogs)."""
        return (now - self.loop_t0) - self.sim_time if self.loop_t0 is not None else 0.0

    def _run(self) -> None:
        now = time.monotonic()
        self.loop_t0 = now - self.sim_time
        next_chunk = next_sensor = next_lc = now
        period = 1.0 / self.rate
        st = self.stats
        while not self._stop.is_set():
            now = time.monotonic()
            fd = self._master
            if fd is not None:
                self._read(fd, now)
            self.firmware.check_watchdog(now)
            n = 0
            while now >= next_chunk and n < CATCH_UP:
                late = now - next_chunk > self.chunk
                if not self.step_chunk(now, next_chunk):   # a new pile: start the schedule afresh
                    now = time.monotonic()
                    next_chunk = now
                    continue
                st.overruns += late
                next_chunk += self.chunk
                n += 1
                now = time.monotonic()
            if now >= next_chunk + self.chunk:        # still behind after CATCH_UP chunks: give the backlog up
                st.resyncs += 1
                st.dropped_s += now - next_chunk
                next_chunk = now + self.chunk
            if fd is not None and now >= next_sensor:
                if self._put(fd, self._tx.encode(self.sensor_frame_now(now))):
                    st.sensor_frames += 1
                next_sensor += period
                if next_sensor < now:
                    next_sensor = now + period
            if fd is not None and self.load_cell and now >= next_lc:
                with self.lock:
                    mass = float(self.sim.loaded_mass) if self.sim.pile is not None else 0.0
                if self._put(fd, self._tx.encode(load_cell_frame(mass, self.device_us(now)))):
                    st.load_cell_frames += 1
                next_lc += LOAD_CELL_PERIOD
                if next_lc < now:
                    next_lc = now + LOAD_CELL_PERIOD
            wait = max(0.0, min(next_chunk, next_sensor, next_lc if self.load_cell else next_sensor) - time.monotonic())
            try:
                if fd is not None:
                    select.select([fd], [], [], wait)
                else:
                    time.sleep(wait)
            except (OSError, ValueError):
                time.sleep(0.001)

    def _read(self, fd: int, now: float) -> None:
        try:
            data = os.read(fd, 4096)
        except (BlockingIOError, OSError):
            return
        wall, mono = time.time(), time.monotonic()     # when the device read these bytes off the line
        for _, msg in self.parser.feed(data):
            self.firmware.receive(msg, now)
            if isinstance(msg, CommandFrame):
                self.command_log.append((wall, mono, msg))

    def _put(self, fd: int, wire: bytes) -> bool:
        try:
            os.write(fd, wire)
            return True
        except OSError:        # no reader yet / buffer full: the frame used its number (a gap)
            self.stats.write_errors += 1
            return False
