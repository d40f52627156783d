"""ROS-free logic of the hardware bridge: /lhd/cmd -> safe device command, watchdog,
wheel-drift detection, joint-state contents, the load cell's validity and report. The node
(bridge_node.py) is thin over this."""
from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass

from .protocol import RAW_MAX, RAW_MIN, CommandFrame, LoadCellFrame, SensorFrame

JOINT_NAMES = ("boom", "bucket", "wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")


class CommandRejected(ValueError):
    """A /lhd/cmd message that must not reach the machine."""


@dataclass(frozen=True)
class BridgeParams:
    wheels_max: float
    boom_speed: float          # |full boom speed|, rad/s
    bucket_speed: float        # full bucket speed, rad/s
    valve_deadband: float
    cmd_timeout: float
    command_rate_hz: float
    device_watchdog: float     # s, the firmware's watchdog (WATCHDOG_MS in lhd_due.ino)
    wheel_radius: float
    drift_slip_ratio: float
    drift_min_speed: float
    drift_current_front: float
    drift_current_rear: float
    odom_timeout: float
    backoff_min: float
    backoff_max: float
    control_period: float = 0.1   # s, the policy's period: the drift window (DriftWindow), as in training

    @classmethod
    def from_config(cls, cfg: dict) -> "BridgeParams":
        c, t, h = cfg["paper"]["control"], cfg["task"], cfg["hardware"]
        return cls(
            wheels_max=c["wheels_max"], boom_speed=abs(c["boom_min"]), bucket_speed=c["bucket_max"],
            valve_deadband=h["valve_deadband"], cmd_timeout=h["cmd_timeout"], command_rate_hz=h["command_rate_hz"],
            device_watchdog=h["device_watchdog"],
            wheel_radius=cfg["machine"]["wheel_radius"], drift_slip_ratio=t["drift_slip_ratio"],
            drift_min_speed=t["drift_min_speed"], drift_current_front=h["drift_current_front"],
            drift_current_rear=h["drift_current_rear"], odom_timeout=h["odom_timeout"],
            backoff_min=h["reconnect_backoff_min"], backoff_max=h["reconnect_backoff_max"],
            control_period=1.0 / c["frequency_hz"],
        )


# ------------------------------------------------------------------ safety rules of the parameters
# (docs/hardware_bridge.md, "Parameters"): each returns what is wrong, or None.
# The longest the machine may run on its last command when /lhd/cmd stops: 10 decisions of the
# 10 Hz policy; at full speed that is 0.37 m of travel (2.7 rad/s x 0.137 m) and 0.19 rad of
# boom lift before the bridge stops it.
CMD_TIMEOUT_MAX = 1.0   # s


def deadband_problem(deadband: float) -> str | None:
    """CommandMapper opens a valve when |u| >= valve_deadband x full speed; with a dead band of
    0 (or less) that holds for u = 0, so a zero command would move the boom and the bucket."""
    if deadband <= 0.0:
        return ("a zero command would open the valves (a valve opens when |u| >= valve_deadband x full speed, "
                "and 0 >= 0); expected a dead band > 0")
    return None


def baud_problem(baud) -> str | None:
    """1200 baud is the Arduino SAM core's erase request: a native USB port opened at 1200 baud whose
    DTR then drops (every close or reconnection) erases the Due's flash and starts its bootloader."""
    if int(baud) == 1200:
        return ("1200 baud erases the Arduino Due's firmware when the port closes (its core's 'touch' reset to the "
                "bootloader); expected the link's rate, 115200")
    return None


def min_command_rate(device_watchdog: float) -> float:
    """The slowest safe command rate: with one command frame lost the device sees two periods
    without a command, and that must fit in half its watchdog (the other half is margin for
    host scheduling and USB latency), so 2 / rate <= device_watchdog / 2."""
    return 4.0 / device_watchdog


def command_rate_problem(rate_hz: float, device_watchdog: float) -> str | None:
    lo = min_command_rate(device_watchdog)
    if rate_hz < lo:
        return (f"one lost command frame would leave the device {2000.0 / rate_hz:.0f} ms without a command, more "
                f"than half its {device_watchdog * 1000.0:.0f} ms watchdog (it would stop the machine); "
                f"expected >= {lo:g} Hz")
    return None


class CommandScheduler:
    """When command frames leave: at the command rate, and at once when the command differs
    from the frame last sent, so a new decision does not wait up to a whole period (20 ms at
    50 Hz) for its frame; never sooner than `min_gap` after the last frame (a teleop stream
    cannot flood the 115,200-baud line). After an early frame the cadence restarts from it, so
    two frames are never further apart than one period (plus the caller's tick): the device
    watchdog's margin (command_rate_problem) is kept."""

    def __init__(self, period: float, min_gap: float, now: float):
        self.period, self.min_gap = float(period), float(min_gap)
        self.next_frame = now
        self.last_sent = None
        self.last_write: float | None = None

    def due(self, now: float, cmd) -> bool:
        if self.last_write is not None and now - self.last_write < self.min_gap:
            return False
        return now >= self.next_frame or (self.last_sent is not None and cmd != self.last_sent)

    def sent(self, now: float, cmd) -> None:
        """A frame carrying `cmd` left at `now` (or was due and tried)."""
        if now < self.next_frame:
            self.next_frame = now + self.period
        else:
            self.next_frame = max(self.next_frame + self.period, now)
        self.last_sent, self.last_write = cmd, now


class CommandMapper:
    """[u_wheels, u_boom, u_bucket] (rad/s) -> CommandFrame for the ternary valves.

    Safety, whatever the command says: wheels never reverse (clamped to [0, wheels_max]), the
    boom is never lowered, the bucket never tilted forward (those requests hold the joint).
    A joint moves (at full speed: the valves are ternary) only when |u| is at least
    valve_deadband of its full speed. NaN, infinities and wrong lengths are rejected.
    """

    def __init__(self, p: BridgeParams):
        self.p = p
        self.rejected = 0
        self.clamped = 0

    def map(self, data) -> CommandFrame:
        vals = list(data)
        if len(vals) != 3:
            self.rejected += 1
            raise CommandRejected(f"/lhd/cmd must hold 3 values [u_wheels, u_boom, u_bucket] in rad/s, got {len(vals)}")
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
            self.rejected += 1
            raise CommandRejected(f"/lhd/cmd has non-finite values {vals}; expected finite rad/s")
        u_w, u_boom, u_bucket = (float(v) for v in vals)
        p = self.p
        clamped = False
        if u_w < 0.0 or u_w > p.wheels_max:
            clamped = True
            u_w = min(max(u_w, 0.0), p.wheels_max)
        valve_boom = 0
        if u_boom > 0.0:          # lowering requested: refused, hold
            clamped = True
        elif -u_boom >= p.valve_deadband * p.boom_speed:
            valve_boom = 1        # raise
        valve_bucket = 0
        if u_bucket < 0.0:        # forward tilt requested: refused, hold
            clamped = True
        elif u_bucket >= p.valve_deadband * p.bucket_speed:
            valve_bucket = 1      # curl back
        if clamped:
            self.clamped += 1
        return CommandFrame(wheel_setpoint=u_w, valve_boom=valve_boom, valve_bucket=valve_bucket, enable=True)


class Watchdog:
    """Stale after `timeout` seconds without a valid command, and until a command arrives
    that is newer than the last (re)connection."""

    def __init__(self, timeout: float):
        self.timeout = timeout
        self.last_valid: float | None = None
        self.armed_since = 0.0
        self.trips = 0
        self._was_stale = True

    def feed(self, now: float) -> None:
        self.last_valid = now

    def rearm(self, now: float) -> None:
        """After a (re)connection or an emergency-stop release: commands from before it no
        longer count. Not a timeout, so not counted as a trip."""
        self.armed_since = now
        self._was_stale = True

    def timed_out(self, now: float) -> bool:
        """No valid command for `timeout` (commands stopped coming), without side effects: not the
        brief wait for a first command after a (re)connection, which `stale` also covers."""
        return self.last_valid is not None and now - self.last_valid >= self.timeout

    def stale(self, now: float) -> bool:
        s = (self.last_valid is None or self.last_valid < self.armed_since
             or now - self.last_valid >= self.timeout)
        if s and not self._was_stale:
            self.trips += 1
        self._was_stale = s
        return s


def detect_drift(f: SensorFrame, slip: tuple[bool, bool] | None, p: BridgeParams) -> tuple[bool, bool]:
    """(front, rear) drift. With the machine's travel known, `slip` (DriftWindow.slips: the training's
    rule, wheel travel against machine travel over the last control period) decides alone. Without it
    (no fresh odometry, or not yet a period of it), the motor currents beyond their no-drift presets:
    the paper's real-machine cue ("power usage of the wheel motors"), the only one left. A current
    alone is not drift while the travel is known: a motor at its limit while it accelerates the
    machine, or stalls with the wheels held (the paper's RLD, stuck with a full bucket, "the front axle
    cannot turn"), draws as much as one whose wheel spins, and the simulator the actors trained in
    counts neither (docs/hardware_bridge.md "Drift")."""
    if slip is not None:
        return slip
    return (f.current_fl > p.drift_current_front or f.current_fr > p.drift_current_front,
            f.current_rear > p.drift_current_rear)


def _interp(ts: list[float], vs: list, t: float):
    """vs at t, linear between the samples of strictly increasing ts around it (t within [ts[0], ts[-1]])."""
    i = bisect.bisect_left(ts, t)
    if i < len(ts) and ts[i] == t:
        return vs[i]
    t0, t1 = ts[i - 1], ts[i]
    w = (t - t0) / (t1 - t0)
    v0, v1 = vs[i - 1], vs[i]
    if isinstance(v0, tuple):
        return tuple(a + w * (b - a) for a, b in zip(v0, v1))
    return v0 + w * (v1 - v0)


def _integral(ts: list[float], vs: list[float], a: float, b: float) -> float:
    """The integral of v from a to b (a <= b within [ts[0], ts[-1]]), v linear between the samples."""
    total, t_prev, v_prev = 0.0, a, _interp(ts, vs, a)
    i = bisect.bisect_right(ts, a)
    while i < len(ts) and ts[i] < b:
        total += 0.5 * (v_prev + vs[i]) * (ts[i] - t_prev)
        t_prev, v_prev = ts[i], vs[i]
        i += 1
    return total + 0.5 * (v_prev + _interp(ts, vs, b)) * (b - t_prev)


DRIFT_ODOM_MAX_AGE = 0.3   # s: the window's odometry image at most this older than the newest wheel frame (the
                           # ArUco odometry arrives 20-110 ms after its image in the twin); older, no answer


class DriftWindow:
    """The simulator's drift rule (LhdSimulator.wheel_drift, what every actor read in training) on the
    machine's own signals: over one control period T ending at the newest odometry's instant t1, a
    wheel drifts when its rim travel r (theta(t1) - theta(t1 - T)) and the machine's travel over the
    same window differ by more than max(drift_min_speed T, drift_slip_ratio x the larger of the two).

    Time-aligned: the machine's travel is the integral of /lhd/odom's speed between its stamps (each
    image's instant, 20-100 ms before the message arrives; the ArUco node's Kalman speed, whose noise
    over a window is a fraction of the 5 mm floor, where the difference of two raw poses would carry
    the marker's 2-5 mm position noise twice), the wheels' from their integrated angles at the frames'
    instants (DeviceClock: the device's clock on the ROS clock), interpolated to t1 - T and t1.
    Comparing the newest wheel speed with the newest (older) camera speed, as the bridge did until
    2026-11-29, flagged drift whenever the machine accelerated. The flags lag the simulator's by the
    odometry's latency: the window ends at the newest image, and an image older than
    DRIFT_ODOM_MAX_AGE against the newest wheel frame gives no answer (the motor currents decide). The
    rear wheels: the device reports the differential's carrier, the mean of the two, where the
    simulator judges each rear wheel.

    ROS-free; the node feeds it from two threads under its own lock. `reason` says why the last
    `travels` had no answer."""

    def __init__(self, period: float, keep_s: float = 2.0, max_age: float = DRIFT_ODOM_MAX_AGE):
        if not period > 0.0:
            raise ValueError(f"drift window period {period!r} s: expected > 0 (the control period)")
        self.period = float(period)
        self.max_age = float(max_age)
        self.keep_s = max(float(keep_s), 3.0 * self.period + self.max_age)
        self._wt: list[float] = []                     # wheel frames: measurement time (ROS clock, s)
        self._wa: list[tuple[float, float, float]] = []   # their angles (fl, fr, rear), rad
        self._ws: list[int] = []                       # their integration segment (WheelAngles.restarts)
        self._ot: list[float] = []                     # odometry: stamp (s)
        self._ov: list[float] = []                     # its speed v_x, m/s
        self.reason = "no odometry yet"

    def add_wheels(self, t: float, angles: tuple[float, float, float], segment: int) -> None:
        """A frame at t; a t not after the last one (a clock stepped back) restarts the history."""
        if self._wt and t <= self._wt[-1]:
            self._wt, self._wa, self._ws = [], [], []
        self._wt.append(float(t))
        self._wa.append(tuple(float(a) for a in angles))
        self._ws.append(int(segment))
        self._trim(self._wt, self._wa, self._ws)

    def add_odom(self, t: float, v: float) -> bool:
        """False (and nothing kept) for a non-finite stamp or speed, or a repeated stamp; a stamp before
        the last one (a camera restart, a clock stepped back) restarts the history."""
        if not (math.isfinite(t) and math.isfinite(v)):
            return False
        if self._ot and t <= self._ot[-1]:
            if t == self._ot[-1]:
                return False
            self._ot, self._ov = [], []
        self._ot.append(float(t))
        self._ov.append(float(v))
        self._trim(self._ot, self._ov)
        return True

    def _trim(self, ts, *lists) -> None:
        cut = bisect.bisect_left(ts, ts[-1] - self.keep_s)
        if cut > 0:
            del ts[:cut]
            for lst in lists:
                del lst[:cut]

    @property
    def newest(self) -> tuple[float | None, float | None]:
        """(newest odometry stamp, newest wheel frame time), s; None where there is none."""
        return (self._ot[-1] if self._ot else None), (self._wt[-1] if self._wt else None)

    def travels(self) -> tuple[float, tuple[float, float, float]] | None:
        """(machine travel m, (angle change of fl, fr, rear) rad) over the newest window both histories
        cover, or None (and `reason`): no period of odometry inside the wheel frames yet, an odometry
        image too old against the newest wheel frame, or a restart of the wheels' integration inside it."""
        if len(self._ot) < 2 or len(self._wt) < 2:
            self.reason = "no odometry yet" if len(self._ot) < 2 else "no wheel frames yet"
            return None
        j = bisect.bisect_right(self._ot, self._wt[-1]) - 1     # the newest image the wheel frames reach
        if j < 1:
            self.reason = (f"odometry stamps ({self._ot[-1]:.3f} s) do not meet the wheel frames' times "
                           f"({self._wt[0]:.3f}-{self._wt[-1]:.3f} s, ROS clock)")
            return None
        t1 = self._ot[j]
        if self._wt[-1] - t1 > self.max_age:
            self.reason = (f"the newest odometry image is {self._wt[-1] - t1:.3f} s older than the newest wheel frame "
                           f"(at most {self.max_age:g} s)")
            return None
        t0 = t1 - self.period
        if t0 < self._ot[0] or t0 < self._wt[0]:
            self.reason = (f"odometry stamps ({self._ot[0]:.3f}-{t1:.3f} s) do not cover a {self.period:g} s window "
                           f"inside the wheel frames' times ({self._wt[0]:.3f}-{self._wt[-1]:.3f} s, ROS clock)")
            return None
        i0, i1 = bisect.bisect_left(self._wt, t0), bisect.bisect_left(self._wt, t1)
        if len(set(self._ws[max(i0 - 1, 0):i1 + 1])) != 1:
            self.reason = "a gap in the wheel frames (their integration restarted) inside the window"
            return None
        dx = _integral(self._ot[:j + 1], self._ov[:j + 1], t0, t1)
        a0, a1 = _interp(self._wt, self._wa, t0), _interp(self._wt, self._wa, t1)
        self.reason = ""
        return dx, tuple(b - a for a, b in zip(a0, a1))

    def slips(self, p: BridgeParams) -> tuple[bool, bool] | None:
        """(front, rear) by the simulator's rule over the window of `travels`, or None."""
        tr = self.travels()
        if tr is None:
            return None
        dx, dtheta = tr
        tol_min = p.drift_min_speed * self.period

        def slip(d: float) -> bool:
            rim = d * p.wheel_radius
            return abs(rim - dx) > max(tol_min, p.drift_slip_ratio * max(abs(rim), abs(dx)))

        return slip(dtheta[0]) or slip(dtheta[1]), slip(dtheta[2])


DEVICE_CLOCK_WINDOW_S = 2.0   # s of frames over which the device clock's offset is the smallest delay seen


class DeviceClock:
    """The instant each sensor frame was measured, on the host's ROS clock: the device's own clock
    (device_time_us, uint32 microseconds, wrap-around unwrapped) plus an offset, the smallest
    (arrival - device time) over the last DEVICE_CLOCK_WINDOW_S: the frame that met the least delay
    on the way (USB, the reader thread). Frames arrive in bursts (one read returns several, all with
    about the same arrival time) and late when the host is busy; the device's clock does not jitter.
    A device clock that goes back or jumps more than WHEEL_GAP_MAX_S (a reset, a lost link) starts the
    estimate over."""

    def __init__(self, window_s: float = DEVICE_CLOCK_WINDOW_S):
        self.window_s = float(window_s)
        self._raw: int | None = None
        self._dev = 0.0                                  # unwrapped device time, s
        self._cands: deque = deque()                     # (device time s, arrival - device time)

    def stamp(self, device_time_us: int, arrival: float) -> float:
        if self._raw is not None:
            dt = ((device_time_us - self._raw) % DEVICE_CLOCK_WRAP_US) * 1e-6
            if 0.0 < dt <= WHEEL_GAP_MAX_S:
                self._dev += dt
            else:
                self._cands.clear()
                self._dev = 0.0
        self._raw = device_time_us
        c = arrival - self._dev
        while self._cands and self._cands[-1][1] >= c:   # monotone deque: the minimum at the front
            self._cands.pop()
        self._cands.append((self._dev, c))
        while self._cands[0][0] < self._dev - self.window_s:
            self._cands.popleft()
        return self._dev + self._cands[0][1]


DEVICE_CLOCK_WRAP_US = 1 << 32     # the device's uint32 microsecond clock wraps every 71.6 min
WHEEL_GAP_MAX_S = 0.5              # a longer gap between sensor frames (a reset, a lost link): not integrated


class WheelAngles:
    """The wheels' angles (rad), integrated from the speeds the device reports over its own clock
    (device_time_us, wrap-around included; a frame after a gap over WHEEL_GAP_MAX_S, or with the
    clock going back, restarts the integration from the angles reached). The device measures the
    wheels' speeds only; a NaN position (as before 2026-11-28) is what JointState allows but what
    robot_state_publisher and tf cannot take, and the project's rule is that no NaN reaches a
    topic. The angles are for display and tf, not a measurement: nothing here controls from them."""

    def __init__(self):
        self.angles = [0.0, 0.0, 0.0, 0.0]        # fl, fr, rl, rr
        self._last: tuple[int, tuple[float, ...]] | None = None   # (device time, speeds) of the last frame
        self.restarts = 0                          # integrations started (the first frame, after each gap)

    def update(self, f: SensorFrame) -> list[float]:
        speeds = (f.wheel_fl, f.wheel_fr, f.wheel_rear, f.wheel_rear)
        if self._last is not None:
            t0, v0 = self._last
            dt = ((f.device_time_us - t0) % DEVICE_CLOCK_WRAP_US) * 1e-6
            if 0.0 < dt <= WHEEL_GAP_MAX_S:
                # trapezoid between the two frames' speeds
                self.angles = [a + 0.5 * (u + v) * dt for a, u, v in zip(self.angles, v0, speeds)]
            else:
                self.restarts += 1
        else:
            self.restarts += 1
        self._last = (f.device_time_us, speeds)
        return list(self.angles)


ARM_ZERO_MAX = 0.35      # rad (20 deg): a larger zero is not a calibration but a sensor mounted wrong


def arm_zero_problem(v) -> str | None:
    """Why a boom_zero / bucket_zero value is refused (None: accepted)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return f"{v!r}: expected the angle in rad the device reports in the attack pose"
    if abs(v) > ARM_ZERO_MAX:
        return (f"{v:g} rad: expected |zero| <= {ARM_ZERO_MAX:g} rad ({math.degrees(ARM_ZERO_MAX):.0f} deg; in rad, not "
                "deg); a larger one means the sensor is mounted or wired wrong: fix it, not the zero")
    return None


def joint_state_arrays(f: SensorFrame, wheels: WheelAngles | None = None,
                       zeros: tuple[float, float] = (0.0, 0.0)) -> tuple[list, list]:
    """(position, velocity) in JOINT_NAMES order. Boom and bucket: the device's angles minus `zeros`, the
    angles it reports in the attack pose (the bridge's boom_zero, bucket_zero: docs/real_machine.md
    "Calibration"). Wheel positions: integrated by `wheels` (0.0 without it); both rear wheels report the rear
    motor's speed (one motor through a differential)."""
    wheel_pos = wheels.update(f) if wheels is not None else [0.0] * 4
    pos = [f.boom_angle - zeros[0], f.bucket_angle - zeros[1], *wheel_pos]
    vel = [f.boom_rate, f.bucket_rate, f.wheel_fl, f.wheel_fr, f.wheel_rear, f.wheel_rear]
    return pos, vel


# ------------------------------------------------------------------ load cell (optional hardware)
LOAD_CELL_TIMEOUT = 0.5   # s without a load-cell frame (sent at 10 Hz) after one: the report is stale
RAW_MEAN_FRAMES = 10      # raw counts averaged for the calibration figure (1 s at 10 Hz)

# diagnostic levels by name (the node maps them onto diagnostic_msgs/DiagnosticStatus; no ROS here)
_OK, _WARN, _ERROR, _STALE = "OK", "WARN", "ERROR", "STALE"


def load_cell_problems(f: LoadCellFrame) -> list[str]:
    """Why the frame's mass must not be published, one reason per flag ([] = a valid mass)."""
    out = []
    if f.stale:
        out.append("stale: no conversion from the load-cell amplifier for 500 ms (HX711 unplugged, unpowered or "
                   "hung; the device power-cycles it)")
    if f.saturated:
        out.append(f"saturated: raw {f.raw} counts is the amplifier's limit ({RAW_MIN} / {RAW_MAX}): the load "
                   "cell's signal is beyond full scale (overload, a loose wire or a broken cell)")
    if not f.calibrated:
        out.append(f"not calibrated: the firmware has no LOAD_CELL_SCALE (raw {f.raw} counts); calibrate it "
                   "(docs/hardware_bridge.md, 'Load cell')")
    if not f.tared:
        out.append("not tared: the device has no zero yet (it averages its first conversions after power-up, with "
                   "the bucket empty, unless built with LOAD_CELL_OFFSET)")
    return out


class LoadCellMonitor:
    """What the bridge does with load-cell frames: `accept(frame, now)` returns the mass (kg) to
    publish, or None with the reasons kept for the report; `report(now)` is the `load_cell`
    status: OK 'no load cell' while the device sends none (optional hardware), OK with the mass,
    WARN (not calibrated / not tared: a setup step missing), ERROR (saturated / stale sensor),
    STALE when the frames stop. Counts frames, published masses and refused frames."""

    def __init__(self):
        self.last: LoadCellFrame | None = None
        self.last_time: float | None = None
        self.last_mass: float | None = None     # kg, the last published (valid) mass
        self.problems: list[str] = []
        self.frames = 0
        self.published = 0
        self.refused = 0
        self._raw = deque(maxlen=RAW_MEAN_FRAMES)

    def accept(self, f: LoadCellFrame, now: float) -> float | None:
        self.frames += 1
        self.last, self.last_time = f, now
        self.problems = load_cell_problems(f)
        if not f.stale:
            self._raw.append(f.raw)
        if self.problems:
            self.refused += 1
            return None
        mass = float(f.mass)
        if not math.isfinite(mass):   # cannot come from an int32 field; never a NaN on a topic
            self.refused += 1
            return None
        self.published += 1
        self.last_mass = mass
        return mass

    def report(self, now: float):
        """(level name, message, values)."""
        f = self.last
        if f is None:
            return _OK, "no load cell (the device sends no load-cell frames; optional hardware)", {"frames": 0}
        age = now - self.last_time
        values = {"frames": self.frames, "published": self.published, "refused": self.refused,
                  "raw_counts": f.raw,
                  "raw_counts_mean": round(sum(self._raw) / len(self._raw), 1) if self._raw else "none",
                  "flags": f.flags, "calibrated": f.calibrated, "tared": f.tared, "saturated": f.saturated,
                  "stale_sensor": f.stale, "device_time_us": f.device_time_us, "age_s": round(age, 3),
                  "mass_kg": round(self.last_mass, 3) if self.last_mass is not None else "none"}
        if age > LOAD_CELL_TIMEOUT:
            return _STALE, f"no load-cell frame for {age:.1f} s (sent at 10 Hz by the device)", values
        if self.problems:
            level = _ERROR if (f.stale or f.saturated) else _WARN
            return level, "mass not published: " + "; ".join(self.problems), values
        return _OK, f"{f.mass:.3f} kg", values
