"""`lhd up twin`: the unchanged real-machine stack of `lhd up real` against the digital twin.

Starts, as separate processes on real DDS:
  twin          lhd_sim_node.twin_node         the MuJoCo machine as the Arduino Due on a pty (in a
                                               temporary folder), the overhead camera (/camera/...),
                                               the LiDAR (/scan), ground truth under /lhd/twin/truth
and then EXACTLY the nodes and parameters of `lhd up real --port <the twin's pty>` (up_real.stack:
bridge, ArUco, LiDAR, end zone, supervisor, mux, teleop, controller on /lhd/cmd/auto, recorder),
every one with the same --params-file (default config/real_machine.yaml); the twin reads its
camera, marker and LiDAR poses from that same file (`machine_params`), so the twin and the nodes
cannot disagree on a pose.

Then, for each attempt, as an operator would: wait for the LiDAR to see the current pile, call
/lhd/arm until the supervisor's preflight passes (the last refusal is shown if it never does),
wait for the attempt's end, for the mass the supervisor takes from the twin's load cell, and for
the twin's new pile (its reset_delay after the end; slopes cycle through --slopes). The pile
sequence is the twin's: pile k has slope slopes[k mod len] and seed seed + k.

Logged per attempt, the simulator's ground truth beside what the stack estimated:
  v_x         /lhd/odom (ArUco node) vs /lhd/twin/truth/odom over the running phase, the truth
              interpolated at each estimate's stamp (both stamped with the image's instant): RMS
  alpha       /lhd/pile/slope at arming (the slope the supervisor and the policy took) vs the truth
  x_max       /lhd/pile/zones (end-zone node) at arming vs /lhd/twin/truth/zones
  drift       the bridge's /lhd/wheel_drift/front|rear vs the truth drift, sampled at each truth
              message during the running phase: agreement (fraction of samples)
  mass        attempts.csv (the supervisor's load-cell median) vs the simulator's loaded mass
Ends with the attempts table (task/attempt_record's, as `lhd attempts`) and the estimation-error
table; with --json the LAST line is one JSON object: success_rate, attempts (per-attempt records
with their errors), refused_piles (piles on which no attempt ran: the slope read outside the armed
range, or the attempt ended while armed; the twin made the next pile), errors (the summary), table
(the attempts summary), run_dir. The twin makes piles until --episodes x len(--slopes) attempts ran;
piles cycle through --slopes, so a slope whose piles are refused gets fewer attempts (the table says
how many); after more refused piles than attempts asked, the run ends (exit 1).

Ctrl-C or SIGTERM stop everything (controller first, bridge then twin last); children die with
the launcher (PR_SET_PDEATHSIG). A node that exits is reported with its log's tail.
Exit status: 0 done (whatever the success rate), 1 a node died or a wait timed out, 2 a bad
argument, 130 interrupted. docs/twin.md is the guide.
"""
from __future__ import annotations

import argparse
import difflib
import math
import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from lhd_loading_ros.task import json_out
from lhd_loading_ros.cli.argtypes import nonneg_int
from lhd_loading_ros.task.cores import usable_cores
from lhd_loading_ros.cli.launcher import Child, _StopOnSignals
from lhd_loading_ros.cli.up_real import (ENDED, default_params_file, format_preflight, make_run_dir, note_crash,
                                         stop_real_stack)
from lhd_loading_ros.cli.up_real import parser as real_parser
from lhd_loading_ros.cli.up_real import check_args as real_check_args
from lhd_loading_ros.cli.up_real import stack
from lhd_loading_ros.ros.params import discovery_wait_s
from lhd_loading_ros.task.config import load_config
from lhd_loading_ros.task.end_zone import nominal_density
from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.zones import Zones

DEFAULT_SLOPES = (15.0, 20.0, 25.0, 30.0)
ARM_RETRY_S = 1.0          # s between /lhd/arm calls while the preflight refuses
SLOPE_REFUSED_S = 5.0      # s of refusals for the pile's slope (the LiDAR reads it outside the armed range) before
                           # the twin makes the next pile: the LiDAR averages scans, so the reading settles in seconds
SLOPE_REFUSAL = "is outside the controller's range"     # task/attempt.py's words for it


def arm_refusal(message: str, waited_s: float, arm_timeout_s: float) -> str:
    """What to do with a refused /lhd/arm: "skip" this pile when the supervisor refuses its slope (read outside
    the range the controller is armed on: the pile will not change, and a pile built at the range's edge may read
    just outside it) for SLOPE_REFUSED_S, and only then (a refusal that also names a missing input is not a
    pile's), "fail" the run on any other refusal after arm_timeout_s (a missing input, a stale sensor: the
    stack is broken), else "retry"."""
    problems = message.removeprefix("not armed: ").split("; ")
    if all(SLOPE_REFUSAL in p for p in problems) and waited_s >= min(SLOPE_REFUSED_S, arm_timeout_s):
        return "skip"
    if waited_s > arm_timeout_s:
        return "fail"
    return "retry"


# before arming: odometry steady (the supervisor's input timeout is 0.5 s: a chain still starting
# up, or starved, would end the attempt as lost_input at once)
STEADY_S, STEADY_N, STEADY_GAP_S = 1.0, 5, 0.25
ZONES_CAUGHT_UP_M = 0.08            # m: the stack's zones are the current pile's (Watch.zones_caught_up)
SLOPE_SETTLE_S = 2.0                # s after a new pile: the slope node's median (filter_max_age 2 s) holds
                                    # only scans of it
EPISODE_SUBSCRIBERS = 5
TWIN_IMU_HZ = 50.0                  # the twin machine's IMU rate (`lhd up twin`, `lhd bench twin`)


class Interrupted(Exception):
    pass



# cores under which the real-time stack starves (docs/twin.md runs 41-42, 48-49 on 2 cores against
# runs 45-47 on 16): the twin, the camera and LiDAR, and ten nodes each keeping up in real time
MIN_CORES = 4

def rms(xs) -> float:
    xs = np.asarray(xs, float)
    return float(np.sqrt(np.mean(xs ** 2))) if xs.size else float("nan")


def odom_age_ms(ages: list[tuple[float, float]], t0: float, t1: float) -> tuple[float | None, float | None]:
    """(median, max) in ms of the odometry's age when it reached this process (arrival minus the
    image's stamp) for the images stamped in [t0, t1]: how old the v_x was that the policy acted on.
    The v_x error is scored at each estimate's stamp and cannot show it."""
    a = [age for t, age in ages if t0 <= t <= t1]
    if not a:
        return None, None
    return float(np.median(a)) * 1e3, float(max(a)) * 1e3


def stack_age_ms(ages: list[tuple[float, float]], camera_lag: dict, t0: float, t1: float
                 ) -> tuple[float | None, float | None, float | None]:
    """(median, max) in ms of the stack's own part of the odometry's age for the images stamped in
    [t0, t1] (the age less the twin's camera lag for that image: the time from the image leaving
    the twin to its odometry arriving here), and the median camera lag itself; images without a
    lag message are left out. None where there is nothing to measure."""
    a, lag = [], []
    for t, age in ages:
        if t0 <= t <= t1:
            c = camera_lag.get(round(t, 6))
            if c is not None:
                a.append(age - c)
                lag.append(c)
    if not a:
        return None, None, None
    return float(np.median(a)) * 1e3, float(max(a)) * 1e3, float(np.median(lag)) * 1e3


def vx_errors(est: list[tuple[float, float]], truth: list[tuple[float, float]], t0: float, t1: float,
              lag: float = 0.0) -> np.ndarray:
    """v_x estimate minus truth for each estimate stamped in [t0, t1], the truth (stamp, v_x)
    interpolated linearly at the estimate's stamp minus `lag` (estimates outside the truth's span
    dropped). lag 0 is the error as the controller and the supervisor live with it."""
    if not est or len(truth) < 2:
        return np.zeros(0)
    tt = np.array([t for t, _ in truth])
    order = np.argsort(tt)
    tt, tv = tt[order], np.array([v for _, v in truth])[order]
    e = np.array([(t, v) for t, v in est if t0 <= t <= t1 and tt[0] <= t - lag <= tt[-1]]).reshape(-1, 2)
    return e[:, 1] - np.interp(e[:, 0] - lag, tt, tv)


def best_lag(est, truth, t0, t1, lags=np.arange(0.0, 0.41, 0.01)) -> tuple[float, float]:
    """(lag s, RMS m/s) of the truth delay that fits the estimate best: the estimator's lag."""
    best = (float("nan"), float("nan"))
    for lag in lags:
        e = vx_errors(est, truth, t0, t1, float(lag))
        if e.size and not rms(e) >= best[1]:
            best = (float(lag), rms(e))
    return best


def agreement(flags: list[tuple[float, bool]], truth: list[tuple[float, bool]]) -> float:
    """Fraction of truth samples (arrival time, flag) where the latest flag (arrival time, flag)
    received at or before it says the same; NaN without samples."""
    if not flags or not truth:
        return float("nan")
    ft = np.array([t for t, _ in flags])
    fv = [f for _, f in flags]
    agree = n = 0
    for t, v in truth:
        i = int(np.searchsorted(ft, t, side="right")) - 1
        if i < 0:
            continue
        n += 1
        agree += fv[i] == v
    return agree / n if n else float("nan")


def pitch_dropped_deg(kin, pose: tuple, joints: dict) -> float:
    """What the stack's `planar_motion` leaves out of the bucket tip's pitch: the tip pitch the
    task's kinematics give with the machine's TRUE orientation minus the pitch with that
    orientation levelled (heading kept, roll and pitch dropped, as the ArUco node publishes
    it), for the same joint angles. The supervisor's final pitch plus this is the true one."""
    from lhd_loading_ros.perception.aruco import level
    from lhd_loading_ros.task.kinematics import quat_to_mat

    _, pos, quat = pose
    T = np.eye(4)
    T[:3, :3] = quat_to_mat(*quat)
    R_level = level(T)[:3, :3]
    pb, pk = joints["boom"][0], joints["bucket"][0]
    art = joints.get("articulation", (0.0, 0.0))[0]
    _, true_pitch, _ = kin.tip_and_bottom(np.asarray(pos), T[:3, :3], pb, pk, art)
    _, level_pitch, _ = kin.tip_and_bottom(np.asarray(pos), R_level, pb, pk, art)
    return math.degrees(true_pitch - level_pitch)


def latest_before(series: list, t: float):
    """The last (stamp, ...) entry of a time-ordered series with stamp <= t (None: none)."""
    i = int(np.searchsorted([e[0] for e in series], t, side="right")) - 1
    return series[i] if i >= 0 else None


def _fmt(v, spec=".3f") -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def machine_pitch_success(records: list[dict]) -> tuple[int, int] | None:
    """(successes, attempts) with the machine's true pitch added to the final pitch, over the
    attempts the stack's success rate counts (task.attempt_record: not aborted; an attempt that
    ended in success or at the timeout only when weighed): those by the paper's test, >= 20 kg and
    phi^T > phi_thresh (task.metrics.success_level), the others (failure, e-stop, lost input)
    as failures. None when no weighed attempt has a corrected pitch."""
    from lhd_loading_ros.task.attempt_record import NEEDS_MASS
    from lhd_loading_ros.task.metrics import success_level

    counted = [r for r in records if r.get("outcome") not in (None, "aborted")
               and (r["outcome"] not in NEEDS_MASS or r.get("mass_csv_kg") is not None)]
    if not any(r["outcome"] in NEEDS_MASS and r.get("phi_final_corrected_deg") is not None for r in counted):
        return None

    def ok(r) -> bool:
        if r["outcome"] not in NEEDS_MASS:
            return False
        phi = r["phi_final_corrected_deg"] if r.get("phi_final_corrected_deg") is not None else r["phi_final_deg"]
        return success_level(r["mass_csv_kg"], math.radians(phi), math.radians(r["phi_thresh_deg"])) >= 1
    return sum(ok(r) for r in counted), len(counted)


def error_summary(records: list[dict]) -> dict:
    """Worst case and mean of each error over the attempts that measured it, and whether the
    issue's bounds hold (v_x RMS <= 0.02 m/s, |alpha| <= 1.5 deg, |x_max| <= 5 cm). alpha is judged
    twice: against the pile's plane (what the controller was told in training) and against the
    slice in the LiDAR's scan plane (the LiDAR's own error); on a plane pile the two are one, on a
    rough pile the first adds the relief of the scanned slice, which no scanner removes."""
    def col(key, absval=True):
        xs = [r[key] for r in records if r.get(key) is not None and math.isfinite(r[key])]
        return [abs(x) for x in xs] if absval else xs

    out = {}
    for key, bound in (("vx_rms", 0.02), ("alpha_err_deg", 1.5), ("alpha_slice_err_deg", 1.5), ("x_max_err_m", 0.05),
                       ("mass_err_kg", None)):
        xs = col(key)
        out[key] = {"max_abs": max(xs) if xs else None, "mean_abs": sum(xs) / len(xs) if xs else None,
                    "n": len(xs), "bound": bound,
                    "within": (bool(xs) and len(xs) == len(records) and max(xs) <= bound) if bound else None}
    for key in ("drift_agree_front", "drift_agree_rear"):
        xs = col(key, absval=False)
        out[key] = {"mean": sum(xs) / len(xs) if xs else None, "min": min(xs) if xs else None, "n": len(xs)}
    return out


def format_errors(records: list[dict], summary: dict) -> str:
    head = (f"{'att':>3} {'slope':>5} {'outcome':<10} {'vx RMS':>7} {'n':>4} {'alpha est':>9} {'err':>6} {'slice':>5} "
            f"{'err':>6} "
            f"{'x_max est':>9} {'truth':>6} {'err':>6} {'drift agree F/R':>15} {'mass csv':>8} {'truth':>6} "
            f"{'err':>6} {'phi end':>7} {'+pitch':>6}")
    lines = ["Estimation errors (stack minus the twin's ground truth)", head, "-" * len(head)]
    for r in records:
        lines.append(
            f"{r['attempt']:>3} {_fmt(r['slope_truth_deg'], '.1f'):>5} {r['outcome']:<10} {_fmt(r['vx_rms']):>7} "
            f"{r['vx_n']:>4} {_fmt(r['alpha_est_deg'], '.2f'):>9} {_fmt(r['alpha_err_deg'], '+.2f'):>6} "
            f"{_fmt(r.get('slice_slope_deg'), '.1f'):>5} {_fmt(r.get('alpha_slice_err_deg'), '+.2f'):>6} "
            f"{_fmt(r['x_max_est_m']):>9} {_fmt(r['x_max_truth_m']):>6} {_fmt(r['x_max_err_m'], '+.3f'):>6} "
            f"{_fmt(r['drift_agree_front'], '.2f'):>7}/{_fmt(r['drift_agree_rear'], '.2f'):<7} "
            f"{_fmt(r['mass_csv_kg'], '.2f'):>8} {_fmt(r['mass_truth_kg'], '.2f'):>6} {_fmt(r['mass_err_kg'], '+.2f'):>6} "
            f"{_fmt(r.get('phi_final_deg'), '.2f'):>7} {_fmt(r.get('phi_final_corrected_deg'), '.2f'):>6}")
    lines.append("-" * len(head))
    s = summary

    def bound(key, unit, scale=1.0):
        d = s[key]
        if d["max_abs"] is None:
            return f"{key}: not measured"
        ok = "within" if d["within"] else "NOT within"
        return (f"{key}: worst {d['max_abs'] * scale:.3f} {unit}, mean {d['mean_abs'] * scale:.3f} {unit} over "
                f"{d['n']} attempt(s): {ok} the bound {d['bound'] * scale:g} {unit}")

    lines.append(bound("vx_rms", "m/s"))
    lags = [(r["vx_best_lag_s"], r["vx_rms_at_best_lag"]) for r in records
            if r.get("vx_best_lag_s") is not None and math.isfinite(r["vx_best_lag_s"])]
    if lags:
        lines.append(f"  (the ArUco v_x lags the truth: best-fitting delay {np.mean([a for a, _ in lags]):.2f} s "
                     f"mean; RMS at that delay worst {max(b for _, b in lags):.3f} m/s)")
    ages = [(r["odom_age_p50_ms"], r["odom_age_max_ms"]) for r in records if r.get("odom_age_p50_ms") is not None]
    if ages:
        worst = max(ages, key=lambda a: a[0])
        lines.append(f"  (odometry age on arrival, image stamp to here: median per attempt {min(a for a, _ in ages):.0f}-"
                     f"{worst[0]:.0f} ms, oldest {max(b for _, b in ages):.0f} ms)")
    split = [(r["stack_age_p50_ms"], r["stack_age_max_ms"], r["twin_camera_lag_p50_ms"]) for r in records
             if r.get("stack_age_p50_ms") is not None]
    if split:
        lines.append(f"  (of which the twin's camera lag, image stamp to leaving the twin: median per attempt "
                     f"{min(c for _, _, c in split):.0f}-{max(c for _, _, c in split):.0f} ms; the stack's own part, "
                     f"image leaving the twin to odometry here: median per attempt {min(a for a, _, _ in split):.0f}-"
                     f"{max(a for a, _, _ in split):.0f} ms, oldest {max(b for _, b, _ in split):.0f} ms)")
    lines.append(bound("alpha_err_deg", "deg"))
    if s.get("alpha_slice_err_deg", {}).get("max_abs") is not None:
        lines.append(bound("alpha_slice_err_deg", "deg") + " (against the slice the LiDAR scans: its own error; "
                     "alpha_err_deg adds that slice's departure from the pile's plane)")
    lines.append(bound("x_max_err_m", "m"))
    m = s["mass_err_kg"]
    if m["max_abs"] is not None:
        lines.append(f"mass_err_kg: worst {m['max_abs']:.2f} kg, mean {m['mean_abs']:.2f} kg")
    drops = [r["phi_dropped_deg"] for r in records if r.get("phi_dropped_deg") is not None]
    if drops:
        flips = [r["attempt"] for r in records if r.get("phi_final_corrected_deg") is not None
                 and r["outcome"] in ("success", "timeout")
                 and (r["phi_final_deg"] > r["phi_thresh_deg"]) != (r["phi_final_corrected_deg"] > r["phi_thresh_deg"])]
        lines.append(f"final pitch: the stack leaves out the machine's own pitch (planar motion; '+pitch' adds the "
                     f"twin's true machine pitch at the end), {np.mean(drops):+.2f} deg mean, {min(drops):+.2f}.."
                     f"{max(drops):+.2f}; attempts whose pitch test the correction turns: "
                     f"{', '.join('#' + str(a) for a in flips) or 'none'}")
        mp = machine_pitch_success(records)
        if mp is not None:
            lines.append(f"success with the machine's pitch added: {mp[0]} / {mp[1]} = {mp[0] / mp[1]:.2f} "
                         f"(what the supervisor would judge with a pitch sensor on the machine)")
    for side in ("front", "rear"):
        d = s[f"drift_agree_{side}"]
        if d["mean"] is not None:
            lines.append(f"drift flag agreement {side}: mean {d['mean']:.3f}, worst {d['min']:.3f}")
    return "\n".join(lines)


class Watch:
    """Everything the launcher listens to (one node, callbacks on the main thread's spin)."""

    def __init__(self, node):
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
        from geometry_msgs.msg import Vector3Stamped
        from nav_msgs.msg import Odometry
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Bool, Float64, Float64MultiArray

        from lhd_loading_ros.ros.qos import LATCHED_QOS, STATUS_QOS

        self.node = node
        self.status: dict = {}              # the latest /lhd/episode key-values
        self.status_log: list[tuple[float, dict]] = []
        self.preflight = None
        self.record_seen: dict = {}         # the record / recorder diagnostics' last keys (up_real.record_diag_line)
        self.record_failed = False
        self.slope = self.zones = None      # the stack's latest estimates
        self.slope_scan_t = -1.0            # ROS time (s) of the scan behind the latest slope
        self.slope_fit = None               # (alpha rad, toe x m) of the latest slope_stamped
        self.truth_slope = self.truth_zones = None
        self.truth_slice_slope = None     # rad, the slope of the slice in the LiDAR's scan plane
        self.piles = 0                      # truth slope messages: one per new pile
        self.pile_t = 0.0                   # ROS time when the latest pile's truth arrived
        self.truth_mass = float("nan")
        self.mass_before_pile = float("nan")
        self.recording = False
        self.odom: list[tuple[float, float]] = []
        self.odom_arrivals: list[float] = []
        self.odom_age: list[tuple[float, float]] = []   # (image stamp, arrival here - stamp), s
        self.camera_lag: dict[float, float] = {}        # image stamp (rounded to 1 us) -> the twin's lag, s
        self.truth_odom: list[tuple[float, float]] = []
        self.truth_pose: list[tuple[float, tuple, tuple]] = []      # (stamp, position, quaternion w x y z)
        self.truth_joints: list[tuple[float, dict]] = []           # (stamp, {name: (position, velocity)})
        self.flags = {"front": [], "rear": []}
        self.truth_drift: list[tuple[float, tuple[bool, bool]]] = []

        def now():
            return node.get_clock().now().nanoseconds * 1e-9

        def stamp(h):
            return h.stamp.sec + h.stamp.nanosec * 1e-9

        def on_status(m):
            kv = {k.key: k.value for k in m.values}
            self.status = kv
            self.status_log.append((now(), kv))

        from lhd_loading_ros.cli.up_real import RECORD_DIAGNOSTICS, record_diag_line

        def on_diag(m):
            for st in m.status:
                if st.name.endswith("supervisor: preflight"):
                    self.preflight = st
                elif st.name.endswith(RECORD_DIAGNOSTICS):
                    # the record or the bags cannot be written: said as it happens, as `lhd up real` does (a review)
                    line = record_diag_line(self.record_seen, st.name, st.level == DiagnosticStatus.ERROR, st.message)
                    if line:
                        print(f"lhd up twin: {line}", file=sys.stderr, flush=True)
                        self.record_failed |= st.level == DiagnosticStatus.ERROR

        def on_odom(m):
            t = now()
            self.odom_arrivals.append(t)
            del self.odom_arrivals[:-50]
            if self.recording:
                self.odom.append((stamp(m.header), float(m.twist.twist.linear.x)))
                self.odom_age.append((stamp(m.header), t - stamp(m.header)))

        def on_camera_lag(m):
            if self.recording and len(m.data) == 2:
                # two frames of a late simulation can share a stamp; the ArUco node uses the first
                self.camera_lag.setdefault(round(float(m.data[0]), 6), float(m.data[1]))

        def on_truth_odom(m):
            if self.recording:
                self.truth_odom.append((stamp(m.header), float(m.twist.twist.linear.x)))
                p, q = m.pose.pose.position, m.pose.pose.orientation
                self.truth_pose.append((stamp(m.header), (p.x, p.y, p.z), (q.w, q.x, q.y, q.z)))

        def on_truth_js(m):
            if self.recording:
                vel = list(m.velocity) + [0.0] * (len(m.name) - len(m.velocity))
                self.truth_joints.append((stamp(m.header), {n: (float(a), float(v)) for n, a, v in
                                                            zip(m.name, m.position, vel)}))

        def on_flag(side):
            def cb(m):
                if self.recording:
                    self.flags[side].append((now(), bool(m.data)))
            return cb

        def on_truth_drift(m):
            if self.recording and len(m.data) == 2:
                self.truth_drift.append((now(), (m.data[0] > 0.5, m.data[1] > 0.5)))

        def on_slope_stamped(m):
            self.slope_scan_t = stamp(m.header)
            self.slope_fit = (float(m.vector.x), float(m.vector.y))

        def on_truth_slope(m):
            self.mass_before_pile = self.truth_mass
            self.truth_slope = float(m.data)
            self.piles += 1
            self.pile_t = now()

        def on_truth_mass(m):
            self.truth_mass = float(m.data)

        sd = qos_profile_sensor_data
        node.create_subscription(DiagnosticStatus, "/lhd/episode", on_status, STATUS_QOS)
        node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 50)
        node.create_subscription(Odometry, "/lhd/odom", on_odom, sd)
        node.create_subscription(Odometry, "/lhd/twin/truth/odom", on_truth_odom, sd)
        node.create_subscription(Float64MultiArray, "/lhd/twin/truth/camera_lag", on_camera_lag, sd)
        node.create_subscription(JointState, "/lhd/twin/truth/joint_states", on_truth_js, sd)
        node.create_subscription(Bool, "/lhd/wheel_drift/front", on_flag("front"), sd)
        node.create_subscription(Bool, "/lhd/wheel_drift/rear", on_flag("rear"), sd)
        node.create_subscription(Float64MultiArray, "/lhd/twin/truth/drift", on_truth_drift, sd)
        node.create_subscription(Float64, "/lhd/twin/truth/loaded_mass", on_truth_mass, sd)
        # slope, zones and their truth are latched (LATCHED_QOS): a late subscriber gets the current pile's
        node.create_subscription(Float64, "/lhd/pile/slope", lambda m: setattr(self, "slope", float(m.data)),
                                 LATCHED_QOS)
        node.create_subscription(Vector3Stamped, "/lhd/pile/slope_stamped", on_slope_stamped, LATCHED_QOS)
        node.create_subscription(Float64MultiArray, "/lhd/pile/zones",
                                 lambda m: setattr(self, "zones", list(m.data)), LATCHED_QOS)
        node.create_subscription(Float64, "/lhd/twin/truth/slope", on_truth_slope, LATCHED_QOS)
        node.create_subscription(Float64, "/lhd/twin/truth/slice_slope",
                                 lambda m: setattr(self, "truth_slice_slope", float(m.data)), LATCHED_QOS)
        node.create_subscription(Float64MultiArray, "/lhd/twin/truth/zones",
                                 lambda m: setattr(self, "truth_zones", list(m.data)), LATCHED_QOS)

    def zones_caught_up(self, own=None) -> bool:
        """The stack's zones are those of the current pile: toe (x_obs_start), x_max and x_cutoff
        within ZONES_CAUGHT_UP_M of the twin's truth (on a plane pile the stack's error is 2-4 cm; a
        previous pile's differ by 0.1-1.4 m), or, given `own` ((alpha, toe) -> Zones: the end-zone
        node's rule), within it of the zones of the slope node's latest fit, a scan taken
        SLOPE_SETTLE_S after the pile was made. On a rough face one scan line's slope is the
        scanned slice's, which differs from the pile's plane by up to 2-3 deg (docs/perception.md
        "Rough faces"): the stack's zones are then this pile's, yet farther than 8 cm from the truth."""
        if self.zones is None:
            return False
        try:
            z = Zones.from_list(self.zones)
            refs = [Zones.from_list(self.truth_zones)] if self.truth_zones is not None else []
            if own is not None and self.slope_fit is not None and self.slope_scan_t > self.pile_t + SLOPE_SETTLE_S:
                refs.append(own(*self.slope_fit))
        except ValueError:
            return False
        return any(all(abs(a - b) <= ZONES_CAUGHT_UP_M for a, b in ((z.x_obs_start, t.x_obs_start), (z.x_max, t.x_max),
                                                                      (z.x_cutoff, t.x_cutoff))) for t in refs)

    def odom_steady(self, t: float) -> bool:
        """STEADY_N odometry messages in the last STEADY_S s, none older than STEADY_GAP_S, all
        after the current pile was made (the machine's new place, not the last attempt's end)."""
        recent = [a for a in self.odom_arrivals if a >= max(t - STEADY_S, self.pile_t)]
        return len(recent) >= STEADY_N and t - recent[-1] <= STEADY_GAP_S

    def start_recording(self):
        self.odom, self.odom_age, self.truth_odom, self.truth_drift = [], [], [], []
        self.camera_lag = {}
        self.truth_pose, self.truth_joints = [], []
        self.flags = {"front": [], "rear": []}
        self.recording = True

    def first_status(self, t_after: float, pred):
        for t, kv in self.status_log:
            if t >= t_after and pred(kv):
                return t, kv
        return None


def twin_parameter_names() -> set[str]:
    """The parameters the twin node declares (its `Param("name", ...)` entries, read from its source
    without starting it), so that a misspelled --twin-param is refused at once instead of being
    ignored by ROS (an undeclared -p override is dropped silently). Empty when the source cannot
    be read: then nothing is checked."""
    import ast
    import importlib.util

    try:
        origin = importlib.util.find_spec("lhd_sim_node.twin_node").origin
        tree = ast.parse(Path(origin).read_text())
    except (ImportError, AttributeError, OSError, SyntaxError, ValueError):
        return set()
    return {n.args[0].value for n in ast.walk(tree)
            if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "Param" and n.args
            and isinstance(n.args[0], ast.Constant) and isinstance(n.args[0].value, str)}


def run_twin(args, real_args, slopes: list[float]) -> int:
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from std_srvs.srv import Trigger

    from lhd_loading_ros.task.attempt_record import csv_path, format_table, read_rows, summarize

    out = sys.stderr if args.json else sys.stdout
    cfg = load_config(real_args.config or None)
    tp_cfg, rho_nominal = TaskParams.from_config(cfg), nominal_density(cfg)

    def own_zones(alpha: float, toe_x: float) -> Zones:
        """The end-zone node's zones for a measured pile (its default density: the config's midpoint)."""
        return Zones.for_measured_pile(alpha, toe_x, rho_nominal, tp_cfg)

    kin = ArmKinematics.from_config(cfg)                                   # the supervisor's kinematics
    phi_thresh_deg = math.degrees(TaskParams.from_config(cfg).phi_thresh_pitch)

    def say(msg):
        print(msg, file=out, flush=True)

    run_dir = make_run_dir(args.run_dir, "twin", "lhd up twin")
    if run_dir is None:
        return 2
    if getattr(real_args, "actor_note", ""):
        say(f"lhd up twin: {real_args.actor_note}")
    cores = usable_cores()          # the affinity, capped by a cgroup CPU quota
    if cores < MIN_CORES:
        say(f"note: {cores} CPU core(s) for the twin and ten real-time nodes: expect late odometry (100-350 ms), "
            f"v_x errors over 0.02 m/s and lost_input endings, above all in the first attempts; "
            f"{MIN_CORES}+ cores give the figures of docs/twin.md runs 45-47")
    log_dir = Path(args.log_dir) if args.log_dir else run_dir / "logs"
    log_dir.mkdir(parents=True, exist_ok=True)
    params_file = Path(real_args.params_file) if real_args.params_file else default_params_file()
    ros_args = ["--params-file", str(params_file)] if params_file else []
    link_dir = Path(tempfile.mkdtemp(prefix="lhd_twin_"))
    link = link_dir / "due"
    real_args.port = str(link)
    real_args.run_dir = str(run_dir)
    total = args.episodes * len(slopes)
    twin_params = {"link": str(link), "machine_params": str(params_file) if params_file else "",
                   "slopes_deg": ",".join(f"{s:g}" for s in slopes), "material": real_args.material,
                   "seed": args.seed, "reset_delay": args.reset_delay, "camera_fps": args.camera_fps,
                   "markers_hz": args.markers_hz}
    if args.imu is not None:
        twin_params["imu_hz"] = TWIN_IMU_HZ
    if real_args.config:
        twin_params["config"] = real_args.config
    for kv in args.twin_param:
        k, _, v = kv.partition("=")
        twin_params[k.strip()] = v.strip()
    quiet = not args.verbose
    stop = threading.Event()
    records: list[dict] = []
    refused: list[dict] = []        # piles on which no attempt ran (never armed, or ended while armed)
    children: list[Child] = []
    rc = 0
    t_start = time.monotonic()

    with _StopOnSignals(stop):
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("lhd_up_twin")
        w = Watch(node)
        arm = node.create_client(Trigger, "/lhd/arm")
        twin_reset = node.create_client(Trigger, "/lhd_twin/reset")

        def now():
            return node.get_clock().now().nanoseconds * 1e-9

        crashed = {"what": "", "at": None}  # the node that died and when it was found, for the record (note_crash)

        def skip_pile(k: int, pile: int, reason: str, attempt: int | None = None) -> None:
            """A pile on which no attempt ran: listed (refused_piles), said, and the twin's next pile now
            (/lhd_twin/reset); the caller tries the same attempt again on it."""
            r = {"pile": pile, "slope_truth_deg": math.degrees(w.truth_slope) if w.truth_slope is not None else None,
                 "alpha_est_deg": math.degrees(w.slope) if w.slope is not None else None, "reason": reason}
            refused.append(r if attempt is None else {**r, "attempt": attempt})
            say(f"attempt {k + 1}/{total}: " + (f"attempt {attempt} ended before it ran" if attempt is not None
                                                else "not armed") + f", next pile: {reason}")
            spin(30.0, lambda: twin_reset.service_is_ready(), "the twin's /lhd_twin/reset service")
            fut_reset = twin_reset.call_async(Trigger.Request())
            done = spin(30.0, lambda: fut_reset.done() and fut_reset.result(), "the answer of /lhd_twin/reset")
            if not done.success:
                raise RuntimeError(f"attempt {k + 1}: the twin could not make the next pile: {done.message}")
            spin(30.0, lambda: w.piles > pile, "the twin's new pile")

        def spin(timeout_s: float, until, what: str):
            """Spin until `until()` is truthy; RuntimeError naming `what` after timeout_s or when a
            node died; Interrupted on Ctrl-C/SIGTERM."""
            t_end = time.monotonic() + timeout_s
            while True:
                v = until()
                if v:
                    return v
                if stop.is_set():
                    raise Interrupted()
                for c in children:
                    if not c.alive():
                        tail = c.log_path.read_text()[-2000:] if quiet else ""
                        crashed["what"] = f"{c.name} exited with status {c.proc.returncode}"
                        crashed["at"] = time.time()
                        raise RuntimeError(f"node `{c.name}` exited with status {c.proc.returncode} while waiting "
                                           f"for {what}:\n{tail}")
                if time.monotonic() > t_end:
                    raise RuntimeError(f"timed out after {timeout_s:.0f} s waiting for {what}")
                rclpy.spin_once(node, timeout_sec=0.05)

        try:
            t_check = time.monotonic() + discovery_wait_s()
            busy = {}
            while not busy and time.monotonic() < t_check and not stop.is_set():
                rclpy.spin_once(node, timeout_sec=0.1)
                busy = {t: n for t in ("/lhd/joint_states", "/lhd/cmd", "/lhd/episode", "/lhd/twin/truth/odom")
                        if (n := node.count_publishers(t))}
            if busy:
                raise RuntimeError(f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')} already has publishers on "
                                   f"{busy}: another LHD stack, simulator or twin is running there. Stop it, or set "
                                   "ROS_DOMAIN_ID to a free domain")
            children.append(Child("twin", "lhd_sim_node.twin_node", twin_params, log_dir, quiet, []))
            spin(120.0, lambda: link.exists() and w.piles >= 1, "the twin's device link and first pile")
            for name, module, params, extra in stack(real_args, run_dir):
                if stop.is_set():
                    raise Interrupted()
                if name == "supervisor" and args.imu:     # a tilt limit asked for; else the parameter file's
                    params = {**params, "max_tilt_deg": float(args.imu)}
                children.append(Child(name, module, params, log_dir, quiet, [*ros_args, *extra]))
            machine = (f"with an IMU ({float(twin_params['imu_hz']):g} Hz)" if args.imu is not None
                       else "without an IMU (--no-imu)")
            say(f"lhd up twin: twin + {len(children) - 1} nodes of `lhd up real` ({real_args.controller} controller) "
                f"on {link}; machine {machine}; "
                f"{total} attempt(s) on slopes {', '.join(f'{s:g}' for s in slopes)} deg; run folder "
                f"{run_dir}; logs in {log_dir}")

            k = 0
            while k < total:
                if len(refused) > total:
                    raise RuntimeError(f"{len(refused)} piles without an attempt that ran, for {total} attempt(s) asked: "
                                       f"the last: {refused[-1]['reason']}")
                pile = w.piles
                # the LiDAR has scanned the current pile (a scan stamped after the pile was made)
                # and zones of this pile: arming on the last attempt's (the end-zone node re-estimates
                # the pile while the machine is in it, and publishes only when they move) failed an
                # attempt 7 ms after its start. The end-zone node republishes on a change of 2 cm, so
                # "this pile's" is: within ZONES_CAUGHT_UP_M of the twin's truth for this pile, or of
                # the end-zone rule at the slope node's fit of a scan SLOPE_SETTLE_S after the pile
                # was made (a rough face: Watch.zones_caught_up)
                spin(60.0, lambda: w.slope_scan_t > w.pile_t and w.zones_caught_up(own_zones),
                     f"the LiDAR slope and end zone of pile {pile} (a scan after the pile was made)")
                # the camera -> ArUco chain delivers odometry steadily, and every node that acts on
                # the attempt status (mux, controller, recorder, twin) has joined the graph
                spin(60.0, lambda: w.odom_steady(now()), "steady odometry from the ArUco node (/lhd/odom: "
                     f"{STEADY_N} messages in the last {STEADY_S:g} s, none older than {STEADY_GAP_S:g} s)")
                n_sub = EPISODE_SUBSCRIBERS if real_args.record else EPISODE_SUBSCRIBERS - 1   # --no-record: no recorder
                spin(60.0, lambda: node.count_subscribers("/lhd/episode") >= n_sub,
                     f"{n_sub} subscribers of /lhd/episode (mux, controller, "
                     f"{'recorder, ' if real_args.record else ''}twin, this one)")
                # arm as soon as the supervisor's preflight passes
                t_arm = time.monotonic()
                last = {"msg": "no answer"}
                armed = False
                while not armed:
                    spin(30.0, lambda: arm.service_is_ready(), "the supervisor's /lhd/arm service")
                    t_call = now()
                    fut = arm.call_async(Trigger.Request())
                    res = spin(10.0, lambda: fut.done() and fut.result(), "the answer of /lhd/arm")
                    armed = res.success
                    last["msg"] = res.message
                    if armed:
                        break
                    decision = arm_refusal(res.message, time.monotonic() - t_arm, args.arm_timeout)
                    if decision == "skip":
                        break
                    if decision == "fail":
                        pf = format_preflight(w.preflight) if w.preflight is not None else ""
                        raise RuntimeError(f"attempt {k + 1}: the supervisor refused to arm for {args.arm_timeout:g} s; "
                                           f"last answer: {last['msg']}\n{pf}")
                    t_retry = time.monotonic() + ARM_RETRY_S
                    spin(ARM_RETRY_S + 1, lambda: time.monotonic() >= t_retry, "the next arming try")
                if not armed:
                    # the pile's slope is read outside the armed range: not an attempt (nothing ran, nothing is
                    # recorded); the twin makes the next pile and the run goes on
                    skip_pile(k, pile, last["msg"])
                    continue            # the same attempt on the next pile
                slope_est, zones_est = w.slope, list(w.zones)
                slope_truth, zones_truth = w.truth_slope, list(w.truth_zones) if w.truth_zones else None
                slice_truth = w.truth_slice_slope
                say(f"attempt {k + 1}/{total}: {res.message}")
                w.start_recording()
                # this attempt's number: the first armed (or running) status since the call; the
                # previous attempt's ended status keeps coming at 2 Hz until then
                number = spin(10.0, lambda: w.first_status(t_call, lambda kv: kv.get("state") in ("armed", "running")),
                              "the armed attempt's status")[1].get("episode")
                run = spin(10.0, lambda: w.first_status(t_call, lambda kv: kv.get("episode") == number and
                                                        kv.get("state") in ("running", *ENDED)), "the attempt to run")
                if run[1].get("state") in ENDED and run[1].get("ran") == "false":
                    # ended while armed (the supervisor aborted it before it ran: the zones moved, a stale input):
                    # recorded, not counted, never weighed (nothing was loaded); the twin makes the next pile
                    w.recording = False
                    skip_pile(k, pile, f"{run[1].get('state')}: {run[1].get('reason', '')}", int(number))
                    continue            # the same attempt on the next pile
                t_run = run[0]
                end = spin(real_args.attempt_timeout + 30.0,
                           lambda: w.first_status(t_call, lambda kv: kv.get("episode") == number and
                                                  kv.get("state") in ENDED), "the attempt's end")
                t_end, kv_end = end
                w.recording = False
                say(f"attempt {number} {kv_end.get('state')}: {kv_end.get('reason', '')}; {kv_end.get('elapsed_s', '?')} "
                    f"s, drift front {kv_end.get('front_drift_pct', '?')} % rear {kv_end.get('rear_drift_pct', '?')} %")
                weighed = spin(args.reset_delay + 20.0, lambda: w.first_status(
                    t_end, lambda kv: kv.get("episode") == number and kv.get("loaded_mass") not in (None, "", "nan")),
                    f"the supervisor's load-cell mass of attempt {number}")[1]
                truth_mass = w.truth_mass if w.piles == pile else w.mass_before_pile
                say(f"attempt {number}: weighed {float(weighed['loaded_mass']):.2f} kg (twin {truth_mass:.2f} kg), "
                    f"SL {weighed.get('success_level', '?')}, success {weighed.get('success', '?')}")
                errs = vx_errors(w.odom, w.truth_odom, t_run, t_end)
                age_p50, age_max = odom_age_ms(w.odom_age, t_run, t_end)
                stack_p50, stack_max, cam_lag_p50 = stack_age_ms(w.odom_age, w.camera_lag, t_run, t_end)
                truth_flags = w.truth_drift
                rec = {"attempt": int(number), "outcome": kv_end.get("state"), "reason": kv_end.get("reason", ""),
                       "elapsed_s": float(kv_end.get("elapsed_s", "nan")),
                       "slope_truth_deg": math.degrees(slope_truth) if slope_truth is not None else None,
                       "alpha_est_deg": math.degrees(slope_est) if slope_est is not None else None,
                       "slice_slope_deg": math.degrees(slice_truth) if slice_truth is not None else None,
                       "vx_rms": rms(errs) if errs.size else None, "vx_bias": float(np.mean(errs)) if errs.size else None,
                       "vx_n": int(errs.size), "odom_age_p50_ms": age_p50, "odom_age_max_ms": age_max,
                       "stack_age_p50_ms": stack_p50, "stack_age_max_ms": stack_max,
                       "twin_camera_lag_p50_ms": cam_lag_p50,
                       "vx_best_lag_s": best_lag(w.odom, w.truth_odom, t_run, t_end)[0],
                       "vx_rms_at_best_lag": best_lag(w.odom, w.truth_odom, t_run, t_end)[1],
                       "x_max_est_m": zones_est[1], "x_max_truth_m": zones_truth[1] if zones_truth else None,
                       "drift_agree_front": agreement(w.flags["front"], [(t, f[0]) for t, f in truth_flags]),
                       "drift_agree_rear": agreement(w.flags["rear"], [(t, f[1]) for t, f in truth_flags]),
                       "drift_truth_front_pct": 100.0 * float(np.mean([f[0] for _, f in truth_flags]))
                       if truth_flags else None,
                       "drift_truth_rear_pct": 100.0 * float(np.mean([f[1] for _, f in truth_flags]))
                       if truth_flags else None,
                       "drift_stack_front_pct": float(kv_end.get("front_drift_pct", "nan")),
                       "drift_stack_rear_pct": float(kv_end.get("rear_drift_pct", "nan")),
                       "mass_csv_kg": None, "mass_truth_kg": truth_mass,
                       "mass_status_kg": float(weighed["loaded_mass"]),
                       "success_level": weighed.get("success_level"), "success": weighed.get("success") == "True"}
                # the final pitch the supervisor judged, and what planar motion left out of it
                # (the machine's true orientation at the end; the end status is published within
                # a 50 Hz check of the end, and the machine's own pitch changes slowly)
                rec["phi_final_deg"] = float(kv_end.get("phi_final_deg", "nan"))
                rec["phi_thresh_deg"] = phi_thresh_deg
                pose_end, js_end = latest_before(w.truth_pose, t_end), latest_before(w.truth_joints, t_end)
                # with --imu the supervisor already has the machine's pitch: nothing is dropped
                rec["phi_dropped_deg"] = (pitch_dropped_deg(kin, pose_end, js_end[1])
                                          if args.imu is None and pose_end is not None and js_end is not None
                                          and "boom" in js_end[1] else None)
                rec["phi_final_corrected_deg"] = (rec["phi_final_deg"] + rec["phi_dropped_deg"]
                                                  if rec["phi_dropped_deg"] is not None else None)
                rec["alpha_err_deg"] = (rec["alpha_est_deg"] - rec["slope_truth_deg"]
                                        if rec["alpha_est_deg"] is not None and rec["slope_truth_deg"] is not None
                                        else None)
                rec["alpha_slice_err_deg"] = (rec["alpha_est_deg"] - rec["slice_slope_deg"]
                                              if rec["alpha_est_deg"] is not None and rec["slice_slope_deg"] is not None
                                              else None)
                rec["x_max_err_m"] = (rec["x_max_est_m"] - rec["x_max_truth_m"]
                                      if rec["x_max_truth_m"] is not None else None)
                for key in ("drift_agree_front", "drift_agree_rear"):
                    if not math.isfinite(rec[key]):
                        rec[key] = None
                records.append(rec)
                # the twin's new pile (also the recorder's post-roll: the bag is closed by then)
                spin(args.reset_delay + 30.0, lambda: w.piles > pile, "the twin's new pile")
                k += 1
        except Interrupted:
            say("\nlhd up twin: interrupted, stopping the nodes")
            rc = 130
        except RuntimeError as exc:
            print(f"lhd up twin: {exc}\n(node logs in {log_dir})", file=sys.stderr)
            rc = 1
        finally:
            # as `lhd up real` stops its stack: the supervisor (it records the live attempt's end),
            # the recorder (its bag holds that end), then the rest, the bridge then the twin last
            stop_real_stack(children, node)
            if crashed["what"]:
                note_crash(run_dir, crashed["what"], "lhd up twin", found_at=crashed["at"])
            shutil.rmtree(link_dir, ignore_errors=True)

    # the record as written by the supervisor
    rows = []
    path = csv_path(run_dir)
    if path.is_file():
        try:
            rows = read_rows(path)
        except ValueError as exc:
            print(f"lhd up twin: {exc}", file=sys.stderr)
    by_number = {r.attempt: r for r in rows}
    for rec in records:
        row = by_number.get(rec["attempt"])
        if row is not None:
            rec["mass_csv_kg"] = row.mass_kg
            rec["bag"] = str(run_dir / row.bag) if row.bag else None
        rec["mass_err_kg"] = (rec["mass_csv_kg"] - rec["mass_truth_kg"]
                              if rec["mass_csv_kg"] is not None and math.isfinite(rec["mass_truth_kg"]) else None)
    summary = summarize(rows)
    err = error_summary(records)
    counted = summary["counted"]
    success_rate = (sum(c["successes"] for c in summary["cells"]) / counted) if counted else None
    wall = time.monotonic() - t_start
    print(format_table(summary, title=f"Twin attempts in {path} ({real_args.controller}, {real_args.material}, "
                                       f"{wall:.0f} s)"), file=out)
    print(file=out)
    print(format_errors(records, err), file=out)
    for r in refused:
        what = f"attempt {r['attempt']} never ran" if "attempt" in r else "never armed"
        print(f"pile {r['pile']} ({_fmt(r['slope_truth_deg'], '.1f')} deg, read {_fmt(r['alpha_est_deg'], '.2f')} deg) "
              f"{what}: {r['reason']}", file=out)
    print(f"success rate {_fmt(success_rate, '.2f')} over {counted} counted attempt(s)"
          f"{f', {len(refused)} pile(s) without an attempt that ran' if refused else ''}; run folder {run_dir}",
          file=out, flush=True)
    if w.record_failed and rc == 0:
        from lhd_loading_ros.cli.up_real import record_failed_message

        print(record_failed_message("lhd up twin", log_dir, run_dir), file=sys.stderr, flush=True)
        rc = 1
    if args.json:
        mp = machine_pitch_success(records)
        print(json_out.dumps({"success_rate": success_rate,
                          "success_rate_machine_pitch": mp[0] / mp[1] if mp else None, "attempts": records, "refused_piles": refused, "errors": err, "table": summary,
                          "run_dir": str(run_dir), "controller": real_args.controller, "slopes": slopes,
                          "episodes_per_slope": args.episodes, "imu": args.imu is not None,
                          "imu_hz": float(twin_params.get("imu_hz", 0.0)), "max_tilt_deg": args.imu or None,
                          "wall_s": wall, "exit": rc}), flush=True)
    return rc


def slope_range_problem(slopes, config: str | None, flag: str = "--slopes") -> str:
    """Why the twin cannot load these slopes under the config it will read ("" if it can): the
    launcher's check (cli/launcher.slope_range_problem), one wording for `lhd up sim`, `lhd up
    twin` and `lhd bench twin`."""
    from lhd_loading_ros.cli.launcher import slope_range_problem as problem
    from lhd_loading_ros.task.config import config_name, load_config

    return problem(slopes, load_config(config or None), flag, config_name(config))


# How far the twin's LiDAR slope may lie from the pile's (0.1-0.4 deg in the twin runs: docs/twin.md)
LIDAR_EDGE_DEG = 0.4


def edge_slopes_note(slopes, lo: float, hi: float, who: str) -> str:
    """A note for slopes within LIDAR_EDGE_DEG of the ends of the range the controller is armed on ("" for
    none): the LiDAR's estimate of such a pile may fall outside, the supervisor then refuses to arm (it
    refuses, it does not clip: issue 14), and the pile is skipped (arm_refusal). A 35 deg twin pile read
    35.1 deg ended a run of `rld_machine` (armed on 14-35 deg) after 60 s of refusals on 2026-11-29."""
    edge = [s for s in slopes if s < lo + LIDAR_EDGE_DEG or s > hi - LIDAR_EDGE_DEG]
    if not edge:
        return ""
    inside = [min(max(s, lo + LIDAR_EDGE_DEG), hi - LIDAR_EDGE_DEG) for s in edge]
    return (f"note: --slopes {' '.join(f'{s:g}' for s in edge)}: within {LIDAR_EDGE_DEG:g} deg of the {lo:g}-{hi:g} deg "
            f"{who} is armed on; the LiDAR's estimate (0.1-0.4 deg off in the twin) may fall outside, the "
            f"supervisor then refuses to arm, and after {SLOPE_REFUSED_S:g} s the twin makes the next pile (not an "
            f"attempt); {' '.join(f'{s:g}' for s in inside)} stay inside")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd up twin", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--controller", choices=("rld", "rlc", "tampier", "teacher"), default="rld")
    ap.add_argument("--policy", help="exported actor for rld/rlc (default: the machine's, policies/rld_drift_confirm_margin8 or rlc_gains, as lhd up real)")
    ap.add_argument("--slopes", type=float, nargs="+", default=list(DEFAULT_SLOPES),
                    help="pile slopes, degrees, cycled (default 15 20 25 30)")
    ap.add_argument("--episodes", type=int, default=3, help="attempts PER SLOPE (default 3: 12 attempts on the "
                                                            "four default slopes)")
    ap.add_argument("--material", choices=["homogeneous", "nonhomogeneous"], default="homogeneous")
    ap.add_argument("--seed", type=nonneg_int, default=0, help="pile k uses seed + k")
    ap.add_argument("--attempt-timeout", type=float, default=10.0, help="s (the paper: 10 s)")
    ap.add_argument("--reset-delay", type=float, default=2.5, help="s from an attempt's end to the twin's new pile "
                                                                   "(the supervisor weighs over 1 s once still)")
    ap.add_argument("--camera-fps", type=float, default=30.0,
                    help="the simulated camera's frame rate (default 30, the real camera's and the twin node's; at 15 "
                         "the v_x error doubles: docs/twin.md, runs 13-16)")
    ap.add_argument("--markers-hz", type=float, default=2.0, help="the twin's MarkerArray rate (0: none)")
    imu = ap.add_mutually_exclusive_group()
    imu.add_argument("--imu", type=float, nargs="?", const=0.0, default=0.0, metavar="MAX_TILT_DEG",
                    help="the default: the machine has an IMU on its rear frame, as config/real_machine.yaml expects "
                         "(/lhd/imu at 50 Hz: orientation with 0.1 deg noise, accelerometer with 0.05 m/s^2 noise and "
                         "a bias of up to 0.1 m/s^2): the ArUco node places the tilting machine with it and "
                         "integrates its acceleration (v_x), the supervisor puts the machine's pitch into the final "
                         "pitch; with MAX_TILT_DEG the supervisor also ends an attempt whose machine tilts beyond it "
                         "(max_tilt_deg; without it the parameter file's: 0, no limit, in config/real_machine.yaml)")
    imu.add_argument("--no-imu", dest="imu", action="store_const", const=None,
                     help="the paper's machine: no IMU (v_x from the camera alone: 0.022-0.027 m/s RMS on the worst "
                          "attempt; with the IMU 0.012-0.028, within 0.02 on 71 of 72 attempts: docs/twin.md)")
    ap.add_argument("--twin-param", action="append", default=[], metavar="NAME=VALUE",
                    help="a parameter of the twin node (lhd_sim_node/twin_node.py), e.g. camera_dropout=0.05, or "
                         "pile_relief_sd=0.03 (a rough face: 3 cm of relief; use --slopes inside the actor's range "
                         "with a margin, e.g. 17 20 25 28); repeatable; a name the twin node does not declare is refused")
    ap.add_argument("--arm-timeout", type=float, default=60.0, help="s of preflight refusals before giving up")
    ap.add_argument("--params-file", help="ROS parameter file of the nodes and the twin's poses "
                                          "(default config/real_machine.yaml)")
    ap.add_argument("--config", help="lhd_params.yaml for every node and the twin (default: as lhd up real: $LHD_CONFIG, else the actor's own, else the package's)")
    ap.add_argument("--no-record", dest="record", action="store_false", help="no rosbag2 per attempt")
    ap.add_argument("--run-dir", help="attempts.csv, bags and logs (default runs/twin/<UTC time>)")
    ap.add_argument("--log-dir", type=Path, help="node logs (default <run-dir>/logs)")
    ap.add_argument("--json", action="store_true", help="progress and tables on stderr; the last stdout line is "
                                                        "one JSON object")
    ap.add_argument("--verbose", action="store_true", help="node logs on this terminal")
    args = ap.parse_args(argv)
    if args.json:             # the JSON alone on stdout (cli/clean_stdout.py)
        from lhd_loading_ros.cli.clean_stdout import reserve_stdout

        reserve_stdout()
    if args.episodes < 1:
        ap.error(f"--episodes must be >= 1 (attempts per slope), got {args.episodes}")
    if args.reset_delay < 1.5:
        ap.error(f"--reset-delay must be >= 1.5 s (the supervisor weighs over 1 s once the machine is still), "
                 f"got {args.reset_delay}")
    known = twin_parameter_names()
    for kv in args.twin_param:
        if "=" not in kv or not kv.partition("=")[0].strip():
            ap.error(f"--twin-param {kv!r}: expected NAME=VALUE, e.g. camera_dropout=0.05")
        name = kv.partition("=")[0].strip()
        if known and name not in known:
            near = difflib.get_close_matches(name, sorted(known), n=1)
            ap.error(f"--twin-param {kv!r}: the twin node has no parameter {name!r}"
                     + (f"; did you mean {near[0]!r}?" if near else "")
                     + f" Its parameters: {', '.join(sorted(known))}")
    if args.arm_timeout <= 0:
        ap.error(f"--arm-timeout must be positive, got {args.arm_timeout}")
    if args.imu is not None and not (math.isfinite(args.imu) and 0.0 <= args.imu <= 45.0):
        ap.error(f"--imu {args.imu:g}: expected a tilt limit in [0, 45] deg (0 or no value: no limit)")
    # the real stack's options, parsed by `lhd up real`'s own parser: its defaults are the twin's
    rargv = ["--port", "(twin)", "--controller", args.controller, "--material", args.material,
             "--attempt-timeout", str(args.attempt_timeout)]
    for flag, val in (("--policy", args.policy), ("--params-file", args.params_file), ("--config", args.config)):
        if val:
            rargv += [flag, val]
    if not args.record:
        rargv.append("--no-record")
    rap = real_parser()
    rap.prog = ap.prog
    rap.error = ap.error       # a refusal shows the twin's usage, not `lhd up real`'s (--port, --settle...: a review)
    real_args = rap.parse_args(rargv)
    real_check_args(rap, real_args)      # sets the actor (the machine's default) and its own parameter file
    from lhd_loading_ros.task.config import ConfigError

    try:
        bad = slope_range_problem(args.slopes, real_args.config)    # the file the twin and the stack will read
    except ConfigError as exc:      # a broken parameter file: one message, exit 2, before any node starts
        ap.error(str(exc))
    if bad:
        ap.error(bad)
    lim = getattr(real_args, "slope_limits", None)
    if lim and any(not lim[0] <= s <= lim[1] for s in args.slopes):
        # the supervisor would refuse to arm them (slope_limits_deg): said now, not after 60 s of refusals
        out = [f"{s:g}" for s in args.slopes if not lim[0] <= s <= lim[1]]
        ap.error(f"--slopes {' '.join(out)}: outside the {lim[0]:g}-{lim[1]:g} deg the machine's default actor "
                 f"{real_args.policy} is armed on (docs/real_machine.md \"Which actor on the machine\"); name it with "
                 f"--policy to use its card's whole range")
    if args.controller in ("rld", "rlc"):
        from lhd_loading_ros.task.config import load_config

        ep = load_config(real_args.config or None)["paper"]["episode"]     # the card's range: its training file's
        lo, hi = float(ep["alpha_min_deg"]), float(ep["alpha_max_deg"])
        if lim:
            lo, hi = max(lo, lim[0]), min(hi, lim[1])
        note = edge_slopes_note(args.slopes, lo, hi, real_args.policy or args.controller)
        if note:
            print(note, file=sys.stderr, flush=True)
    return run_twin(args, real_args, list(args.slopes))


if __name__ == "__main__":
    raise SystemExit(main())
