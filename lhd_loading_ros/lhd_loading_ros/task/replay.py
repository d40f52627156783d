"""An attempt's metrics from its recorded topics (ROS-free; `lhd replay`, cli/replay.py, reads
the bag and hands the time series here).

Times are the bag's receive stamps in ns. Definitions (docs/recording.md):

* the attempt runs from the first `running` status of the attempt to its first end status
  (success, failure, timeout, estop, lost_input, aborted);
* elapsed_s: end status's `stamp_ns` minus the running status's `stamp_ns` (the publisher's own
  clock: supervisor or sim time), or their receive times when the statuses carry no stamp;
* drift %: each command (/lhd/cmd) received while the attempt runs is one control step; the
  step samples the latest front / rear drift flag received at or before it; the percentage of
  steps with the flag set is task.metrics.drift_pct, as in the simulator (one flag per control
  step at 10 Hz). Steps before the first flag of an axle are not counted for that axle;
* final pitch: phi_shovel of the task state (task.kinematics.state_from_measurements) at the
  last joint state received at or before the end, with the odometry closest in time to it
  (within ODOM_GAP_S).
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

from lhd_loading_ros.task.kinematics import ArmKinematics, state_from_measurements
from lhd_loading_ros.task.metrics import drift_pct
from lhd_loading_ros.task.recording import END_STATES, attempt_number

ODOM_GAP_S = 0.25       # a joint state is paired with odometry at most this far from it in time


@dataclass
class Series:
    """Values with their receive times (ns), in time order."""
    t: list = field(default_factory=list)
    v: list = field(default_factory=list)

    def add(self, t_ns: int, value) -> None:
        if self.t and t_ns < self.t[-1]:         # keep time order if a storage returned it out of order
            i = bisect.bisect_right(self.t, t_ns)
            self.t.insert(i, t_ns)
            self.v.insert(i, value)
        else:
            self.t.append(t_ns)
            self.v.append(value)

    def __len__(self) -> int:
        return len(self.t)

    def latest_at(self, t_ns: int):
        """(time, value) of the last sample at or before t_ns, or None."""
        i = bisect.bisect_right(self.t, t_ns)
        return (self.t[i - 1], self.v[i - 1]) if i else None

    def nearest(self, t_ns: int, max_gap_ns: int):
        """(time, value) of the sample closest to t_ns (either side), if within max_gap_ns."""
        i = bisect.bisect_right(self.t, t_ns)
        best = None
        for j in (i - 1, i):
            if 0 <= j < len(self.t) and abs(self.t[j] - t_ns) <= max_gap_ns:
                if best is None or abs(self.t[j] - t_ns) < abs(self.t[best] - t_ns):
                    best = j
        return (self.t[best], self.v[best]) if best is not None else None

    def between(self, t0: int, t1: int) -> "Series":
        """Samples with t0 <= t <= t1."""
        i, j = bisect.bisect_left(self.t, t0), bisect.bisect_right(self.t, t1)
        return Series(self.t[i:j], self.v[i:j])


@dataclass
class Window:
    attempt: int | None
    t_start: int | None           # receive time of the first running status (ns)
    t_end: int | None             # receive time of the first end status (ns)
    start_status: dict | None
    end_status: dict | None
    last_status: dict | None      # the attempt's last status in the bag


def attempt_window(statuses: Series, attempt: int | None) -> Window:
    """The running period of `attempt` from the episode statuses (values: key/value dicts).
    Statuses of other attempts (a latched history of earlier ones) are ignored; attempt None
    takes the attempt of the last running status in the bag."""
    if attempt is None:
        running = [v for v in statuses.v if v.get("state") == "running"]
        attempt = attempt_number(running[-1]) if running else None
        if attempt is None and statuses.v:
            attempt = attempt_number(statuses.v[-1])
    mine = [(t, v) for t, v in zip(statuses.t, statuses.v) if attempt_number(v) == attempt]
    start = next(((t, v) for t, v in mine if v.get("state") == "running"), None)
    end = next(((t, v) for t, v in mine if v.get("state") in END_STATES and (start is None or t >= start[0])), None)
    return Window(attempt, start[0] if start else None, end[0] if end else None, start[1] if start else None,
                  end[1] if end else None, mine[-1][1] if mine else None)


def elapsed_s(w: Window) -> float | None:
    if w.start_status is None or w.end_status is None:
        return None
    try:
        a, b = int(w.start_status["stamp_ns"]), int(w.end_status["stamp_ns"])
        if b >= a:
            return (b - a) / 1e9
    except (KeyError, ValueError):
        pass
    return (w.t_end - w.t_start) / 1e9


def drift_at_commands(cmd_times: list, flags: Series) -> list[bool]:
    """The latest flag at or before each command; commands before the first flag are skipped."""
    out = []
    for t in cmd_times:
        s = flags.latest_at(t)
        if s is not None:
            out.append(bool(s[1]))
    return out


def attempt_drift(cmds: Series, front: Series, rear: Series, w: Window) -> dict:
    """Front and rear drift % over the commands received while the attempt ran, up to the end
    of the bag when it holds no end (None where the bag has no commands or no flags then)."""
    out = {"steps": 0, "front_drift_pct": None, "rear_drift_pct": None, "front_samples": 0, "rear_samples": 0}
    if w.t_start is None:
        return out
    steps = cmds.between(w.t_start, w.t_end if w.t_end is not None else 2**63 - 1).t
    out["steps"] = len(steps)
    for name, flags in (("front", front), ("rear", rear)):
        samples = drift_at_commands(steps, flags)
        out[f"{name}_samples"] = len(samples)
        out[f"{name}_drift_pct"] = drift_pct(samples) if samples else None
    return out


@dataclass
class TipSample:
    t: int
    x: float
    z: float
    pitch: float


def tip_track(kin: ArmKinematics, joints: Series, odom: Series, max_gap_s: float = ODOM_GAP_S) -> list[TipSample]:
    """The bucket tip in the pile frame at each joint state (values: name -> (pos, vel)),
    with the odometry closest in time to it (values: ((x, y, z), (w, x, y, z), v_x)): the two
    come from different nodes (bridge, ArUco) at their own rates, in no fixed order. Joint states
    with no odometry within max_gap_s, or with a NaN or an unusable quaternion, are skipped."""
    out = []
    gap = int(max_gap_s * 1e9)
    for t, js in zip(joints.t, joints.v):
        od = odom.nearest(t, gap)
        if od is None:
            continue
        pos, quat, v_x = od[1]
        try:
            s = state_from_measurements(kin, pos, quat, v_x, js, False, False)
        except ValueError:
            continue
        if all(math.isfinite(v) for v in (s.x_shovel, s.z_shovel, s.phi_shovel)):
            out.append(TipSample(t, s.x_shovel, s.z_shovel, s.phi_shovel))
    return out


def final_pitch(track: list[TipSample], w: Window) -> float | None:
    """phi_shovel (rad) at the last tip sample at or before the end (the last one when the
    attempt has no end in the bag)."""
    if not track:
        return None
    if w.t_end is None:
        return track[-1].pitch
    before = [s for s in track if s.t <= w.t_end]
    return before[-1].pitch if before else None


def command_stats(cmds: Series, w: Window) -> dict:
    """Commands received while the attempt ran: count, rate, max |u| per axis; and the delay
    from the end status to the first all-zero command after it (the stop)."""
    out = {"count": 0, "rate_hz": None, "max_abs": [None, None, None], "first_zero_after_end_ms": None}
    if w.t_start is None:
        return out
    t1 = w.t_end if w.t_end is not None else (cmds.t[-1] if cmds.t else w.t_start)
    during = cmds.between(w.t_start, t1)
    out["count"] = len(during)
    if len(during) >= 2 and during.t[-1] > during.t[0]:
        out["rate_hz"] = (len(during) - 1) / ((during.t[-1] - during.t[0]) / 1e9)
    if len(during):
        out["max_abs"] = [max(abs(float(u[i])) for u in during.v) for i in range(3)]
    if w.t_end is not None:
        after = cmds.between(w.t_end, cmds.t[-1] if cmds.t else w.t_end)
        z = next((t for t, u in zip(after.t, after.v) if all(float(x) == 0.0 for x in u)), None)
        if z is not None:
            out["first_zero_after_end_ms"] = (z - w.t_end) / 1e6
    return out


def pile_toe_x(zones: list | None, toe: float | None, x_init_obs: float) -> tuple[float, str]:
    """Where the pile's toe is in the pile frame, and from what: the LiDAR's /pile/toe, else
    the zones (x_obs_start = toe - x_init_obs, Zones.for_measured_pile), else 0 (the simulator's
    pile frame has its origin at the toe)."""
    if toe is not None and math.isfinite(toe):
        return toe, "pile/toe"
    if zones is not None and len(zones) == 8 and math.isfinite(zones[4]):
        return zones[4] + x_init_obs, "pile/zones"
    return 0.0, "assumed at x = 0 (no pile/toe or pile/zones in the bag)"
