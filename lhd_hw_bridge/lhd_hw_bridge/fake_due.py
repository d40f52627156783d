"""`lhd-fake-due`: an emulator of the LHD's Arduino Due on a pseudo-terminal.

It speaks the device side of docs/serial_protocol.md: receives command and heartbeat
frames, runs a small plant (the arm joints integrate their ternary valve commands at full
speed within their limits, the wheels follow the set-point with a first-order lag, motor
currents follow the load), sends sensor frames at `rate` Hz (the arm's rates, as the firmware's, the
differences of the angles it sends over the last 0.1 s: task/arm_sensors.py), and stops by itself (the
firmware's watchdog) when command frames stop for `watchdog` seconds. Like the firmware, it
clamps the wheel set-point to [0, 2.7] rad/s, never lowers the boom or tilts the bucket forward,
closes a valve at its joint limit, holds everything while the emergency stop is pressed, and
reports in each sensor frame what the valves really do and its flags. Faults can be injected:
sensor noise, dropped frames, corrupted bytes, front or rear drift (wheel spin and high motor
current), the emergency stop (`estop`), motor currents (`currents`), frames of an unknown type
(`send_raw`). `unplug()` closes the pty (the host sees the port vanish); `plug()` opens a new
one behind the same symlink.

With `load_cell=True` (`--load-cell`) it is a device fitted with the bucket's load cell and sends
load-cell frames (type 0x04) at 10 Hz, as the firmware built with LHD_HAS_LOAD_CELL: the
amplifier's raw counts are LOAD_CELL_OFFSET + (bucket_mass + noise) x LOAD_CELL_SCALE, clipped to
the 24-bit range (so a mass beyond about +-96 kg saturates it, as a real overload does), and the
mass field is what the firmware computes from them. A test sets `bucket_mass` (kg),
`load_cell_noise` (kg, standard deviation per conversion) and the faults `load_cell_calibrated`,
`load_cell_tared` (False: the flag cleared and the mass sent as 0) and `load_cell_stale` (the
amplifier stops converting: the last raw value is repeated with the stale flag).
"""
from __future__ import annotations

import argparse
import os
import random
import select
import signal
import sys
import threading
import time
from dataclasses import dataclass, field

from lhd_loading_ros.task.arm_sensors import RATE_WINDOW_S, RateWindow

from .pty_link import close_pty, open_pty
from .protocol import (ANGLE_SCALE, FLAG_ENABLED, FLAG_ESTOP, FLAG_HELD, FLAG_RESET, FLAG_SENSOR_FAULT,
                       FLAG_WATCHDOG, LC_CALIBRATED, LC_SATURATED, LC_STALE, LC_TARED,
                       RAW_MAX, RAW_MIN, TYPE_COMMAND, TYPE_HEARTBEAT, CommandFrame, FrameParser, LoadCellFrame,
                       SensorFrame, TxSequence)

BOOM_SPEED = 0.191
BUCKET_SPEED = 0.2
BOOM_RANGE = (-1.0, 0.05)
BUCKET_RANGE = (-0.1, 1.4)
WHEEL_TAU = 0.1
WHEEL_MAX = 2.7
# the emulated load cell's calibration (the firmware's LOAD_CELL_OFFSET / LOAD_CELL_SCALE): a
# 50 kg, 2 mV/V cell at 3.3 V excitation into the HX711's +-12.9 mV full scale (gain 128) gives
# 6.6 mV / 12.9 mV x 2^23 counts at 50 kg, about 85,800 counts per kg
LOAD_CELL_OFFSET = 150_000     # counts with the bucket empty
LOAD_CELL_SCALE = 85_800.0     # counts per kg
LOAD_CELL_PERIOD = 0.1         # s, one load-cell frame every 100 ms (10 Hz)


def _move(angle: float, rate: float, limits: tuple[float, float], dt: float) -> tuple[float, float]:
    """A hydraulic joint at `rate` for dt, stopped by its limits: (new angle, actual rate)."""
    new = min(max(angle + rate * dt, limits[0]), limits[1])
    return new, (new - angle) / dt


@dataclass
class Plant:
    boom: float = 0.0
    bucket: float = 0.0
    boom_rate: float = 0.0
    bucket_rate: float = 0.0
    wheel_fl: float = 0.0
    wheel_fr: float = 0.0
    wheel_rear: float = 0.0
    valve_boom: int = 0
    valve_bucket: int = 0
    wheel_setpoint: float = 0.0
    enabled: bool = False

    def step(self, dt: float, drift_front: bool, drift_rear: bool) -> None:
        # valve +1 raises the boom (its angle decreases), +1 curls the bucket (angle increases)
        self.boom, self.boom_rate = _move(self.boom, -BOOM_SPEED * self.valve_boom, BOOM_RANGE, dt)
        self.bucket, self.bucket_rate = _move(self.bucket, BUCKET_SPEED * self.valve_bucket, BUCKET_RANGE, dt)
        a = min(dt / WHEEL_TAU, 1.0)
        target = self.wheel_setpoint if self.enabled else 0.0
        self.wheel_fl += a * (target * (1.6 if drift_front else 1.0) - self.wheel_fl)
        self.wheel_fr += a * (target - self.wheel_fr)
        self.wheel_rear += a * (target * (1.6 if drift_rear else 1.0) - self.wheel_rear)


@dataclass
class FakeDue:
    link: str | None = None
    rate: float = 100.0
    watchdog: float = 0.25
    noise: float = 0.0
    drop: float = 0.0
    corrupt: float = 0.0
    drift_front: bool = False
    drift_rear: bool = False
    estop: bool = False                       # the emergency-stop button, pressed
    boom_sensor_fault: bool = False           # the boom angle reads NaN (sent as -32768, flag bit 4), as the firmware
    currents: tuple[float, float, float] | None = None   # (fl, fr, rear) A reported instead of the model's
    load_cell: bool = False                   # fitted with the bucket's load cell: sends load-cell frames
    bucket_mass: float = 0.0                  # kg in the bucket, what the load cell weighs
    load_cell_noise: float = 0.0              # kg, standard deviation of each conversion
    load_cell_calibrated: bool = True         # False: a firmware without LOAD_CELL_SCALE
    load_cell_tared: bool = True              # False: no zero yet (taring at power-up)
    load_cell_stale: bool = False             # the amplifier stopped converting
    silent: bool = False                      # sends no sensor frames (a frozen firmware, a broken RX wire); still reads
    seed: int = 0
    plant: Plant = field(default_factory=Plant)

    def __post_init__(self):
        self.rng = random.Random(self.seed)
        self.parser = FrameParser(accept={TYPE_COMMAND, TYPE_HEARTBEAT})
        self.received: list[tuple[float, object]] = []  # (monotonic time, frame) for tests
        self.watchdog_trips = 0
        self.sent = 0
        self.load_cell_sent: list[LoadCellFrame] = []    # every load-cell frame handed to the link, for tests
        self._lc_raw = LOAD_CELL_OFFSET
        self._lc_time_us = 0
        self._tx = TxSequence()
        self._command: CommandFrame | None = None
        self._rate_windows = (RateWindow(RATE_WINDOW_S), RateWindow(RATE_WINDOW_S))
        self._rate_t, self._rates_now = None, (0.0, 0.0)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._master = self._slave = None
        self.path = None
        self._last_cmd = None
        self._tripped = False
        self.held = True        # as the firmware: stopped after power-up until a stop frame (enable = 0)
        self.was_reset = True   # flag bit 5 until the first stop frame (reset(): as after a reset)
        self._thread = None

    # ------------------------------------------------------------------ pty
    def plug(self) -> str:
        with self._lock:
            self._master, self._slave, self.path = open_pty(self.link)
            self.parser.reset_link()
            return self.link or self.path

    def unplug(self) -> None:
        with self._lock:
            close_pty(self._master, self._slave)
            self._master = self._slave = None
            if self.link and os.path.lexists(self.link):
                os.unlink(self.link)

    # ------------------------------------------------------------------ loop
    def start(self) -> "FakeDue":
        if self._master is None:
            self.plug()
        self._thread = threading.Thread(target=self._run, name="fake-due", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread:
            self._thread.join(timeout=2.0)
        self.unplug()

    def _run(self) -> None:
        period = 1.0 / self.rate
        t_next = time.monotonic()
        t_prev = t_next
        t0 = getattr(self, "_run_t0", None) or t_next
        t_next_lc = t_next
        while not self._stop.is_set():
            now = time.monotonic()
            with self._lock:
                fd = self._master
            if fd is not None:
                self._read(fd, now)
            dt = now - t_prev
            t_prev = now
            self._apply_watchdog(now)
            self._apply_command()
            if dt > 0:
                self.plant.step(dt, self.drift_front, self.drift_rear)
            if fd is not None and now >= t_next:
                if not self.silent:
                    self._send(fd, now - t0)
                t_next += period
                if t_next < now:
                    t_next = now + period
            if fd is not None and self.load_cell and now >= t_next_lc:
                self._send_load_cell(fd, now - t0)
                t_next_lc += LOAD_CELL_PERIOD
                if t_next_lc < now:
                    t_next_lc = now + LOAD_CELL_PERIOD
            r = [fd] if fd is not None else []
            timeout = max(0.0, min(t_next - time.monotonic(), 0.005))
            try:
                select.select(r, [], [], timeout) if r else time.sleep(timeout)
            except (OSError, ValueError):
                time.sleep(0.001)

    def _read(self, fd: int, now: float) -> None:
        try:
            data = os.read(fd, 4096)
        except BlockingIOError:
            return
        except OSError:
            return
        for _, msg in self.parser.feed(data):
            self.received.append((now, msg))
            if isinstance(msg, CommandFrame):
                self._last_cmd = now
                self._command = msg
                self._tripped = False   # a fresh valid command re-arms the machine
                if not msg.enable and not self.estop and not self.boom_sensor_fault:
                    self.held = self.was_reset = False   # a stop frame clears the hold

    def _apply_watchdog(self, now: float) -> None:
        """As the firmware: no command frame for `watchdog` s after one was received -> stopped
        (flag bit 1) until the next command frame."""
        if self._command is not None and not self._tripped and now - self._last_cmd > self.watchdog:
            self._tripped = True
            self.watchdog_trips += 1

    def _apply_command(self) -> None:
        """The outputs from the last command, as the firmware's apply_outputs()."""
        c, p = self._command, self.plant
        if self.estop or self.boom_sensor_fault:
            self.held = True            # released, the machine stays stopped until a stop frame
            self._command = CommandFrame.stop()     # the firmware forgets the command
        run = c is not None and c.enable and not self._tripped and not self.estop and not self.held
        p.enabled = run
        p.wheel_setpoint = min(max(c.wheel_setpoint, 0.0), WHEEL_MAX) if run else 0.0
        boom = max(c.valve_boom, 0) if run else 0        # lowering refused (not a maintenance build)
        bucket = max(c.valve_bucket, 0) if run else 0    # forward tilt refused
        p.valve_boom = 0 if boom > 0 and p.boom <= BOOM_RANGE[0] else boom          # closed at the joint limit
        p.valve_bucket = 0 if bucket > 0 and p.bucket >= BUCKET_RANGE[1] else bucket

    def _send(self, fd: int, t: float) -> None:
        p = self.plant
        n = lambda: self.rng.gauss(0.0, self.noise) if self.noise else 0.0  # noqa: E731
        cur = lambda w, drift: 1.5 + 0.8 * abs(w) + (10.0 if drift else 0.0)  # noqa: E731
        currents = self.currents or (cur(p.wheel_fl, self.drift_front), cur(p.wheel_fr, False),
                                     cur(p.wheel_rear, self.drift_rear) + 2.0)
        boom, bucket = p.boom + n() * 1e-3, p.bucket + n() * 1e-3
        if self._rate_t is None or t > self._rate_t:    # the rates as the firmware's arm_rate.h: over the last 0.1 s
            self._rate_t = t
            self._rates_now = (self._rate_windows[0].push(t, boom), self._rate_windows[1].push(t, bucket))
        if self.boom_sensor_fault:
            boom = -32768 * ANGLE_SCALE           # the firmware's sentinel for NaN
        frame = SensorFrame(
            device_time_us=int(t * 1e6), boom_angle=boom, bucket_angle=bucket,
            boom_rate=self._rates_now[0], bucket_rate=self._rates_now[1], wheel_fl=p.wheel_fl + n() * 1e-2,
            wheel_fr=p.wheel_fr + n() * 1e-2, wheel_rear=p.wheel_rear + n() * 1e-2,
            current_fl=currents[0], current_fr=currents[1], current_rear=currents[2], valve_boom=p.valve_boom,
            valve_bucket=p.valve_bucket,
            flags=(FLAG_ENABLED if p.enabled else 0) | (FLAG_WATCHDOG if self._tripped else 0)
            | (FLAG_ESTOP if self.estop else 0) | (FLAG_HELD if self.held else 0)
            | (FLAG_SENSOR_FAULT if self.boom_sensor_fault else 0) | (FLAG_RESET if self.was_reset else 0))
        if self._put(fd, self._tx.encode(frame)):
            self.sent += 1

    def load_cell_frame(self, t: float) -> LoadCellFrame:
        """The frame the firmware would send now: the amplifier's conversion of the bucket's mass
        (unless it is stale), clipped to 24 bits like the HX711, and the firmware's mass from it."""
        if not self.load_cell_stale:
            noise = self.rng.gauss(0.0, self.load_cell_noise) if self.load_cell_noise else 0.0
            raw = round(LOAD_CELL_OFFSET + (self.bucket_mass + noise) * LOAD_CELL_SCALE)
            self._lc_raw = min(max(raw, RAW_MIN), RAW_MAX)
            self._lc_time_us = int(t * 1e6) & 0xFFFFFFFF
        raw = self._lc_raw
        valid = self.load_cell_calibrated and self.load_cell_tared
        mass = round((raw - LOAD_CELL_OFFSET) / LOAD_CELL_SCALE, 3) if valid else 0.0
        flags = ((LC_CALIBRATED if self.load_cell_calibrated else 0) | (LC_TARED if self.load_cell_tared else 0)
                 | (LC_SATURATED if raw in (RAW_MIN, RAW_MAX) else 0) | (LC_STALE if self.load_cell_stale else 0))
        return LoadCellFrame(self._lc_time_us, mass, raw, flags)

    def _send_load_cell(self, fd: int, t: float) -> None:
        frame = self.load_cell_frame(t)
        self.load_cell_sent.append(frame)
        self._put(fd, self._tx.encode(frame))   # its own sequence counter (per type)

    def _put(self, fd: int, encoded: bytes) -> bool:
        """One frame onto the line, through the injected faults (a dropped frame used its number:
        the host sees the gap). True when written."""
        wire = bytearray(encoded)
        if self.drop and self.rng.random() < self.drop:
            return False
        if self.corrupt and self.rng.random() < self.corrupt:
            i = self.rng.randrange(len(wire) - 1)
            wire[i] ^= 1 << self.rng.randrange(8)
        try:
            os.write(fd, bytes(wire))
            return True
        except OSError:
            return False

    def send_raw(self, wire: bytes) -> None:
        """Put bytes on the line as they are (frames of an unknown type, garbage)."""
        with self._lock:
            if self._master is not None:
                os.write(self._master, wire)

    def reset(self) -> None:
        """What a reset of the Due leaves (power, brown-out, its watchdog): no command, held and flagged
        reset until a stop frame."""
        self._command, self._last_cmd, self._tripped = None, None, False
        self.held = self.was_reset = True

    def last_commands(self) -> list:
        return [(t, m) for t, m in self.received if isinstance(m, CommandFrame)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd-fake-due", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--link", default="/tmp/lhd_due", help="symlink to the pty's device (the bridge's `port`)")
    ap.add_argument("--rate", type=float, default=100.0, help="sensor frames per second")
    ap.add_argument("--watchdog", type=float, default=0.25, help="s without command frames before the device stops")
    ap.add_argument("--noise", type=float, default=0.0, help="sensor noise (standard deviation, scaled per signal)")
    ap.add_argument("--drop", type=float, default=0.0, help="probability of dropping a sensor frame")
    ap.add_argument("--corrupt", type=float, default=0.0, help="probability of flipping a bit in a sensor frame")
    ap.add_argument("--drift-front", action="store_true", help="inject front wheel drift")
    ap.add_argument("--drift-rear", action="store_true", help="inject rear wheel drift")
    ap.add_argument("--estop", action="store_true", help="start with the emergency stop pressed")
    ap.add_argument("--load-cell", action="store_true",
                    help="fitted with the bucket's load cell: load-cell frames at 10 Hz")
    ap.add_argument("--bucket-mass", type=float, default=0.0, help="kg in the bucket (with --load-cell)")
    ap.add_argument("--load-cell-noise", type=float, default=0.0, help="kg, load-cell noise (standard deviation)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    dev = FakeDue(link=args.link, rate=args.rate, watchdog=args.watchdog, noise=args.noise, drop=args.drop,
                  corrupt=args.corrupt, drift_front=args.drift_front, drift_rear=args.drift_rear, estop=args.estop,
                  load_cell=args.load_cell, bucket_mass=args.bucket_mass, load_cell_noise=args.load_cell_noise,
                  seed=args.seed)
    path = dev.plug()
    print(f"fake Due on {dev.path} (link {path})", flush=True)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    signal.signal(signal.SIGINT, lambda *_: done.set())
    dev.start()
    done.wait()
    dev.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
