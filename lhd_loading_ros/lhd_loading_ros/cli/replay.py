"""`lhd replay BAG [--plot OUT.png] [--video OUT.gif|OUT.mp4] [--json]`: an attempt's metrics from its rosbag2 (MCAP or
sqlite3, as the recorder node or `ros2 bag record` wrote it), read with rosbags; no ROS needed.

Prints the outcome and reason, the attempt number, elapsed time, front / rear drift %, final
pitch, loaded mass, the commands (count, rate, max |u| per axis, the stop after the end), each
computed from the recorded topics (task/replay.py says how) next to what the supervisor or
sim node reported in its last /lhd/episode status. --plot draws the bucket tip's path in the XZ
plane of the pile frame (kinematics of task/kinematics.py from /lhd/odom + /lhd/joint_states)
over the pile face and the end zone, and the three commands over time. --video animates the
attempt in side view (cli/replay_video.py: pile, machine, tip trail, zones, FEE force, status). A topic missing from the
bag is said in a line (what cannot be computed without it); a path that is not a bag: exit 2.
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

from lhd_loading_ros.task import json_out
from lhd_loading_ros.task.recording import attempt_number
from lhd_loading_ros.task.replay import (Series, attempt_drift, attempt_window, command_stats, elapsed_s, final_pitch,
                                         pile_toe_x, tip_track)

STORAGE_FILES = (".mcap", ".db3")


class ReplayError(Exception):
    """Not a readable bag: a message and exit status 2."""


@dataclass
class Recording:
    path: Path
    storage: str
    prefix: str
    custom: dict
    duration_s: float
    counts: dict                                  # topic -> messages
    types: dict                                   # topic -> type
    status: Series = field(default_factory=Series)
    cmd: Series = field(default_factory=Series)
    front: Series = field(default_factory=Series)
    rear: Series = field(default_factory=Series)
    joints: Series = field(default_factory=Series)
    odom: Series = field(default_factory=Series)
    slope: Series = field(default_factory=Series)
    zones: Series = field(default_factory=Series)
    end_zone: Series = field(default_factory=Series)
    toe: Series = field(default_factory=Series)
    bad: dict = field(default_factory=dict)       # topic -> messages that could not be used
    start_ns: int = 0                             # the bag's first receive time
    extra: dict = field(default_factory=dict)     # topic suffix -> Series (read_bag's extra handlers)


def bag_dir(path: Path) -> Path:
    """The rosbag2 folder for a folder or for its storage file; ReplayError otherwise."""
    if not path.exists():
        raise ReplayError(f"{path}: no such file or folder")
    if path.is_file() and path.suffix in STORAGE_FILES:
        path = path.parent
    if not path.is_dir():
        raise ReplayError(f"{path} is not a rosbag2 folder (expected a folder with metadata.yaml and a .mcap or .db3)")
    if not (path / "metadata.yaml").is_file():
        if any(f.suffix in STORAGE_FILES for f in path.iterdir()):
            raise ReplayError(f"{path} has a storage file but no metadata.yaml: the recording was never closed "
                              f"(the recorder killed with SIGKILL, or the machine lost power); `lhd bag recover "
                              f"{path}` rewrites what was flushed as a complete bag")
        raise ReplayError(f"{path} is not a rosbag2 folder (no metadata.yaml)")
    return path


def _meta(path: Path) -> tuple[str, dict]:
    import yaml

    try:
        info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise ReplayError(f"{path}/metadata.yaml is not rosbag2 metadata: {exc}") from None
    return str(info.get("storage_identifier", "?")), dict(info.get("custom_data") or {})


def _prefix(custom: dict, types: dict) -> str:
    if custom.get("lhd.prefix"):
        return custom["lhd.prefix"]
    eps = [t for t, ty in types.items() if t.endswith("/episode") and ty == "diagnostic_msgs/msg/DiagnosticStatus"]
    return eps[0][: -len("/episode")] if len(eps) == 1 else "/lhd"


def read_bag(path: Path, extra: dict | None = None) -> Recording:
    """The bag's series; `extra` maps more topic suffixes (after the prefix) to converters, whose
    series land in Recording.extra (the video's twin topics)."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    path = bag_dir(Path(path))
    storage, custom = _meta(path)
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY))
        reader.open()
    except (AnyReaderError, OSError) as exc:
        # a storage file cut off after metadata.yaml was written (an interrupted copy) reads so: recover it
        raise ReplayError(f"{path} cannot be read as a rosbag2: {exc}; if its file was cut off (an interrupted "
                          f"copy, the recorder killed), `lhd bag recover {path}` writes what it holds as a "
                          "complete bag") from None
    try:
        types = {c.topic: c.msgtype for c in reader.connections}
        counts: dict = {}
        for c in reader.connections:
            counts[c.topic] = counts.get(c.topic, 0) + c.msgcount
        pre = _prefix(custom, types)
        rec = Recording(path, storage, pre, custom, reader.duration / 1e9, counts, types, start_ns=reader.start_time)
        handlers = {
            f"{pre}/episode": (rec.status, lambda m: {kv.key: kv.value for kv in m.values}),
            f"{pre}/cmd": (rec.cmd, lambda m: _vector(m.data, 3)),
            f"{pre}/wheel_drift/front": (rec.front, lambda m: bool(m.data)),
            f"{pre}/wheel_drift/rear": (rec.rear, lambda m: bool(m.data)),
            f"{pre}/joint_states": (rec.joints, _joints),
            f"{pre}/odom": (rec.odom, _odom),
            f"{pre}/pile/slope": (rec.slope, lambda m: _finite(m.data)),
            f"{pre}/pile/zones": (rec.zones, lambda m: _vector(m.data, 8)),
            f"{pre}/pile/end_zone": (rec.end_zone, lambda m: _vector(m.data, 3)),
            f"{pre}/pile/toe": (rec.toe, lambda m: _finite(m.point.x)),
        }
        for suffix, convert in (extra or {}).items():
            rec.extra[suffix] = Series()
            handlers[f"{pre}{suffix}"] = (rec.extra[suffix], convert)
        conns = [c for c in reader.connections if c.topic in handlers]
        for conn, t, raw in reader.messages(connections=conns):
            series, convert = handlers[conn.topic]
            try:
                series.add(t, convert(reader.deserialize(raw, conn.msgtype)))
            except (ValueError, AttributeError, TypeError, AnyReaderError):
                rec.bad[conn.topic] = rec.bad.get(conn.topic, 0) + 1
        return rec
    finally:
        reader.close()


def _finite(v) -> float:
    v = float(v)
    if not math.isfinite(v):
        raise ValueError("not finite")
    return v


def _vector(data, n: int) -> list[float]:
    vals = [float(x) for x in data]
    if len(vals) != n or not all(math.isfinite(x) for x in vals):
        raise ValueError(f"expected {n} finite values")
    return vals


def _joints(m) -> dict:
    vel = list(m.velocity)
    return {name: (float(m.position[i]) if i < len(m.position) else math.nan, float(vel[i]) if i < len(vel) else 0.0)
            for i, name in enumerate(m.name)}


def _odom(m):
    p, o = m.pose.pose.position, m.pose.pose.orientation
    return (float(p.x), float(p.y), float(p.z)), (float(o.w), float(o.x), float(o.y), float(o.z)), float(m.twist.twist.linear.x)


def _num(values: dict | None, key: str) -> float | None:
    if not values or key not in values:
        return None
    try:
        v = float(values[key])
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def _record_row(rec: Recording, attempt: int | None):
    """(the attempt's row of <run_dir>/attempts.csv, why the record cannot be read): read as `lhd attempts`
    reads it (task.attempt_record.read_rows: a duplicated attempt, a decimal comma are refused, not taken
    quietly), when the bag sits in <run_dir>/bags/. (None, None) where there is no record or no such row."""
    from lhd_loading_ros.task.attempt_record import read_rows

    path = rec.path.parent.parent / "attempts.csv"
    if attempt is None or rec.path.parent.name != "bags" or not path.is_file():
        return None, None
    try:
        rows = read_rows(path)
    except (OSError, ValueError) as exc:
        return None, f"the run's record cannot be read (no mass or outcome from it): {exc}"
    row = next((r for r in rows if r.attempt == attempt), None)
    name = rec.path.name.removesuffix("_recovered")          # lhd bag recover's copy is the attempt's bag too
    if row is not None and row.bag and Path(row.bag).name != name:
        # the number was used again (bags/attempt_0003_2 beside attempt_0003): the record's row of that number is
        # the other attempt's, whose bag it names (a review, 2026-11-30: its outcome and mass were taken)
        return None, (f"the record's attempt {attempt} names the bag {row.bag}, not this one ({rec.path.name}: the "
                      "number was used twice): no mass or outcome taken from it")
    return row, None


def analyse(rec: Recording, cfg: dict) -> dict:
    from lhd_loading_ros.task.attempt_record import never_ran
    from lhd_loading_ros.task.kinematics import ArmKinematics
    from lhd_loading_ros.task.params import TaskParams

    p = TaskParams.from_config(cfg)
    pre = rec.prefix
    missing = []
    attempt = attempt_number({"episode": rec.custom.get("lhd.attempt")})
    w = attempt_window(rec.status, attempt)
    row, record_problem = _record_row(rec, w.attempt)
    # ended while armed (aborted, e-stop, a silent input): nothing was loaded, and its pitch is from before arming
    ran = not ((w.end_status or {}).get("ran") == "false" or (row is not None and never_ran(row)))
    if not len(rec.status):
        missing.append(f"no {pre}/episode in the bag: outcome, attempt window, elapsed time, drift and commands "
                       f"per attempt unknown")
    elif w.t_start is None:
        missing.append(f"no 'running' status of attempt {w.attempt} in {pre}/episode: the attempt never ran "
                       f"(or the bag began after it ended)")
    elif w.t_end is None:
        missing.append(f"no end status of attempt {w.attempt} in {pre}/episode: the bag ends before the attempt "
                       f"(recorder stopped during it); figures up to the last message"
                       + ("; the outcome from attempts.csv" if row is not None else ""))
    if record_problem:
        missing.append(record_problem)
    last = w.last_status or {}
    outcome, reason = (w.end_status or last).get("state"), (w.end_status or last).get("reason", "")
    if w.end_status is None and row is not None:
        # the bag has no end (a recovered bag: the recorder died): the record's outcome, not the last status's
        outcome, reason = row.outcome, row.reason
    out = {
        "bag": str(rec.path), "storage": rec.storage, "duration_s": rec.duration_s,
        "messages": sum(rec.counts.values()), "topics": dict(sorted(rec.counts.items())),
        "attempt": w.attempt, "outcome": outcome, "reason": reason, "end_in_bag": w.end_status is not None,
        "outcome_source": "attempts.csv" if w.end_status is None and row is not None else f"{pre}/episode",
        "ran": ran,
        "controller": last.get("controller"), "slope_deg": _num(last, "slope_deg"), "material": last.get("material"),
        "note": rec.custom.get("lhd.note"),
    }
    out["elapsed_s"] = elapsed_s(w)
    out["elapsed_reported_s"] = _num(w.end_status, "elapsed_s")
    for axle, series in (("front", rec.front), ("rear", rec.rear)):
        if not len(series):
            missing.append(f"no {pre}/wheel_drift/{axle} in the bag: no {axle} drift %")
    if not len(rec.cmd):
        missing.append(f"no {pre}/cmd in the bag: no commands, no drift % (sampled at each command)")
    d = attempt_drift(rec.cmd, rec.front, rec.rear, w)
    out.update(front_drift_pct=d["front_drift_pct"], rear_drift_pct=d["rear_drift_pct"], drift_steps=d["steps"],
               front_drift_reported_pct=_num(w.end_status, "front_drift_pct"),
               rear_drift_reported_pct=_num(w.end_status, "rear_drift_pct"))
    # tip and pitch
    kin = ArmKinematics.from_config(cfg)
    track = []
    if not len(rec.odom):
        missing.append(f"no {pre}/odom in the bag: no tip trajectory, no final pitch")
    if not len(rec.joints):
        missing.append(f"no {pre}/joint_states in the bag: no tip trajectory, no final pitch")
    if len(rec.odom) and len(rec.joints):
        track = tip_track(kin, rec.joints, rec.odom)
        if not track:
            missing.append(f"{pre}/joint_states and {pre}/odom never give a usable state (boom and bucket "
                           f"positions, a unit quaternion, odometry before the joints): no tip trajectory")
    phi = final_pitch(track, w) if ran else None
    out["final_pitch_deg"] = math.degrees(phi) if phi is not None else None
    out["final_pitch_reported_deg"] = _num(w.end_status, "phi_final_deg")
    in_attempt = [s for s in track if (w.t_start is None or s.t >= w.t_start) and (w.t_end is None or s.t <= w.t_end)]
    out["tip"] = {"samples": len(track), "samples_in_attempt": len(in_attempt),
                  "start_xz": [in_attempt[0].x, in_attempt[0].z] if in_attempt else None,
                  "end_xz": [in_attempt[-1].x, in_attempt[-1].z] if in_attempt else None,
                  "max_z": max(s.z for s in in_attempt) if in_attempt else None}
    # mass: the last status, else the run's record
    mass = _num(last, "loaded_mass")
    source = f"{pre}/episode" if mass is not None else None
    if mass is None and row is not None and row.mass_kg is not None:
        mass, source = row.mass_kg, "attempts.csv"
    out["loaded_mass_kg"], out["mass_source"] = mass, source
    out["success_level"] = last.get("success_level")
    out["commands"] = command_stats(rec.cmd, w)
    # pile
    t_ref = w.t_end if w.t_end is not None else (rec.status.t[-1] if rec.status.t else 2**63 - 1)

    def latest(series):
        s = series.latest_at(t_ref) or (series.latest_at(2**63 - 1) if len(series) else None)
        return s[1] if s else None

    slope, zones, end_zone, toe = latest(rec.slope), latest(rec.zones), latest(rec.end_zone), latest(rec.toe)
    toe_x, toe_from = pile_toe_x(zones, toe, p.x_init_obs)
    out["pile"] = {"slope_deg": math.degrees(slope) if slope is not None else None, "zones": zones,
                   "end_zone": end_zone, "toe_x": toe_x, "toe_from": toe_from}
    if slope is None:
        missing.append(f"no {pre}/pile/slope in the bag: no pile face in the plot")
    if end_zone is None and zones is None:
        missing.append(f"no {pre}/pile/end_zone or {pre}/pile/zones in the bag: no end zone in the plot")
    for topic, n in rec.bad.items():
        missing.append(f"{n} message(s) on {topic} unusable (wrong length or not finite): left out")
    out["missing"] = missing
    out["_track"], out["_window"], out["_h_pile"], out["_d_cutoff"] = track, w, p.h_pile, p.d_cutoff
    return out


def _f(v, fmt="{:.2f}", none="-") -> str:
    return none if v is None else fmt.format(v)


def format_text(m: dict) -> str:
    lines = [f"bag: {m['bag']} ({m['storage']}, {m['duration_s']:.2f} s, {m['messages']} messages on "
             f"{len(m['topics'])} topics)"]
    if m.get("note"):
        lines.append(f"note: {m['note']}")
    head = f"attempt {m['attempt'] if m['attempt'] is not None else '?'}: {m['outcome'] or 'unknown outcome'}"
    if m["reason"]:
        head += f" ({m['reason']})"
    if not m.get("end_in_bag", True) and m["attempt"] is not None:
        head += (" [from attempts.csv; no end in the bag]" if m.get("outcome_source") == "attempts.csv"
                 else " [no end in the bag]")
    if not m.get("ran", True):
        head += ": it ended while armed and never ran"
    lines.append(head)
    ctx = [f"controller {m['controller']}" if m["controller"] else "",
           f"slope {m['slope_deg']:.1f} deg" if m["slope_deg"] is not None else "",
           f"material {m['material']}" if m["material"] else ""]
    if any(ctx):
        lines.append(", ".join(c for c in ctx if c))
    lines.append(f"{'':22}{'from the bag':>14}{'reported':>12}")
    rows = [("elapsed (s)", m["elapsed_s"], m["elapsed_reported_s"]),
            ("front drift (%)", m["front_drift_pct"], m["front_drift_reported_pct"]),
            ("rear drift (%)", m["rear_drift_pct"], m["rear_drift_reported_pct"]),
            ("final pitch (deg)", m["final_pitch_deg"], m["final_pitch_reported_deg"])]
    for name, mine, rep in rows:
        lines.append(f"{name:22}{_f(mine):>14}{_f(rep):>12}")
    lines.append(f"drift sampled at {m['drift_steps']} command(s) of the attempt")
    if not m.get("ran", True):
        lines.append("loaded mass: none, the attempt never ran (nothing was loaded; no final pitch)")
    elif m["loaded_mass_kg"] is not None:
        lines.append(f"loaded mass: {m['loaded_mass_kg']:.2f} kg ({m['mass_source']})"
                     + (f", success level {m['success_level']}" if m.get("success_level") not in (None, "") else ""))
    else:
        lines.append("loaded mass: not weighed yet (the bag closes before the weighing: `lhd attempt mass KG`, "
                     "then attempts.csv has it)")
    c = m["commands"]
    mx = c["max_abs"]
    lines.append(f"commands during the attempt: {c['count']}"
                 + (f" ({c['rate_hz']:.1f} Hz)" if c["rate_hz"] else "")
                 + (f"; max |u| wheels {mx[0]:.3f}, boom {mx[1]:.3f}, bucket {mx[2]:.3f} rad/s" if c["count"] else ""))
    if c["first_zero_after_end_ms"] is not None:
        lines.append(f"stop: first zero command {c['first_zero_after_end_ms']:.0f} ms after the end status")
    tip = m["tip"]
    if tip["samples_in_attempt"]:
        lines.append(f"bucket tip: {tip['samples_in_attempt']} samples, from x {tip['start_xz'][0]:.3f} z "
                     f"{tip['start_xz'][1]:.3f} to x {tip['end_xz'][0]:.3f} z {tip['end_xz'][1]:.3f} m "
                     f"(highest z {tip['max_z']:.3f} m)")
    for line in m["missing"]:
        lines.append(f"missing: {line}")
    return "\n".join(lines)


def _title(m: dict) -> str:
    """The plot's title: the attempt, its outcome and time; said when the bag holds no end (the outcome
    then from attempts.csv, if it has one) and when the attempt never ran."""
    t = f"attempt {m['attempt']}: {m['outcome']}" + (f", {m['elapsed_s']:.2f} s" if m["elapsed_s"] else "")
    if not m.get("end_in_bag", True) and m["attempt"] is not None:
        t += " (attempts.csv; no end in the bag)" if m.get("outcome_source") == "attempts.csv" else " (no end in the bag)"
    if not m.get("ran", True):
        t += " (never ran)"
    return t


def plot(m: dict, rec: Recording, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon, Rectangle

    w, track = m["_window"], m["_track"]
    t0 = w.t_start if w.t_start is not None else (min(rec.cmd.t + [s.t for s in track]) if (rec.cmd.t or track) else 0)
    fig = plt.figure(figsize=(12, 6.5))
    gs = fig.add_gridspec(3, 2, width_ratios=(1.25, 1.0))
    ax = fig.add_subplot(gs[:, 0])
    pile = m["pile"]
    xs = [s.x for s in track] or [0.0]
    zs = [s.z for s in track] or [0.0]
    top = max(max(zs), m["_h_pile"]) + 0.1
    left, right = min(xs + [pile["toe_x"]]) - 0.1, max(xs) + 0.3
    if pile["slope_deg"] is not None:
        a = math.radians(pile["slope_deg"])
        L = m["_h_pile"] / math.tan(a)
        toe = pile["toe_x"]
        right = max(toe + L, max(xs)) + 0.3
        ax.add_patch(Polygon([(toe, 0.0), (toe + L, m["_h_pile"]), (right, m["_h_pile"]), (right, 0.0)], closed=True,
                             facecolor="0.8", edgecolor="0.4", label=f"pile face {pile['slope_deg']:.1f} deg "
                             f"(toe from {pile['toe_from'].split(' (')[0]})"))
    ez = pile["end_zone"] or (pile["zones"][:3] if pile["zones"] else None)
    if ez is not None:
        ax.add_patch(Rectangle((ez[0], ez[2]), ez[1] - ez[0], top - ez[2], facecolor="tab:green", alpha=0.25,
                               edgecolor="tab:green", label="end zone"))
    if pile["zones"]:
        ax.axvline(pile["zones"][3], color="tab:red", ls="--", lw=1, label="cutoff (restricted beyond)")
    if track:
        inside = [s for s in track if (w.t_start is None or s.t >= w.t_start) and (w.t_end is None or s.t <= w.t_end)]
        ax.plot(xs, zs, color="0.6", lw=1, label="bucket tip (whole bag)")
        if inside:
            ax.plot([s.x for s in inside], [s.z for s in inside], color="tab:blue", lw=2, label="bucket tip (attempt)")
            ax.plot(inside[0].x, inside[0].z, "o", color="tab:blue")
            ax.plot(inside[-1].x, inside[-1].z, "s", color="tab:blue")
    else:
        ax.text(0.5, 0.5, "no tip trajectory\n(odom / joint_states missing)", transform=ax.transAxes, ha="center")
    ax.set_xlabel("x in the pile frame (m)")
    ax.set_ylabel("z (m)")
    ax.set_xlim(left, right)
    ax.set_ylim(min(min(zs), 0.0) - 0.05, top)
    ax.set_aspect("equal", adjustable="box")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=2, fontsize=8)
    ax.set_title(_title(m))
    ts = [(t - t0) / 1e9 for t in rec.cmd.t]
    for i, name in enumerate(("u_wheels", "u_boom", "u_bucket")):
        a = fig.add_subplot(gs[i, 1])
        if ts:
            a.step(ts, [u[i] for u in rec.cmd.v], where="post", color="tab:orange")
        else:
            a.text(0.5, 0.5, "no commands in the bag", transform=a.transAxes, ha="center")
        for t_mark, label in ((w.t_start, "running"), (w.t_end, "end")):
            if t_mark is not None:
                a.axvline((t_mark - t0) / 1e9, color="k", ls=":", lw=1)
                if i == 0:
                    a.text((t_mark - t0) / 1e9, 1.02, label, transform=a.get_xaxis_transform(), fontsize=8)
        a.set_ylabel(f"{name} (rad/s)")
        if i == 2:
            a.set_xlabel("time from running (s)")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="lhd replay", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bag", help="rosbag2 folder (or its .mcap / .db3 file)")
    ap.add_argument("--plot", metavar="OUT.png", help="write the tip trajectory and the commands here")
    ap.add_argument("--json", action="store_true", help="the metrics as one JSON object")
    ap.add_argument("--video", metavar="OUT.gif|OUT.mp4", help="an animation of the attempt, side view "
                    "(cli/replay_video.py): GIF always, MP4 with imageio-ffmpeg installed")
    ap.add_argument("--fps", type=float, default=10.0, help="video frames per second of bag time (default 10)")
    ap.add_argument("--config", help="parameter file (default: the shipped config/lhd_params.yaml)")
    args = ap.parse_args(argv)
    from lhd_loading_ros.task.config import ConfigError, load_config

    try:
        cfg = load_config(args.config)
    except (ConfigError, OSError) as exc:
        print(f"lhd replay: {exc}", file=sys.stderr)
        return 2
    extra = None
    if args.plot:
        # checked before the bag is read: matplotlib's own refusal came as a traceback (a review)
        import matplotlib

        matplotlib.use("Agg")
        from matplotlib.figure import Figure

        kinds = Figure().canvas.get_supported_filetypes()
        suffix = Path(args.plot).suffix.lstrip(".").lower()
        if suffix and suffix not in kinds:          # (no suffix: matplotlib writes a PNG)
            print(f"lhd replay: --plot {args.plot}: expected a file ending in one of "
                  f"{', '.join('.' + k for k in sorted(kinds))} (the image's format)", file=sys.stderr)
            return 2
    if args.video:
        from lhd_loading_ros.cli import replay_video

        problem = replay_video.check_output(Path(args.video), args.fps)
        if problem:
            print(f"lhd replay: {problem}", file=sys.stderr)
            return 2
        extra = replay_video.EXTRA_TOPICS
    try:
        rec = read_bag(Path(args.bag), extra)
    except ReplayError as exc:
        print(f"lhd replay: {exc}", file=sys.stderr)
        return 2
    m = analyse(rec, cfg)
    if args.plot:
        try:
            plot(m, rec, Path(args.plot))
        except OSError as exc:
            print(f"lhd replay: cannot write the plot {args.plot}: {exc}", file=sys.stderr)
            return 2
        m["plot"] = str(args.plot)
    if args.video:
        try:
            m["video"] = replay_video.render(m, rec, cfg, Path(args.video), args.fps)
        except (OSError, replay_video.VideoError) as exc:
            print(f"lhd replay: cannot write the video {args.video}: {exc}", file=sys.stderr)
            return 2
    public = {k: v for k, v in m.items() if not k.startswith("_")}
    if args.json:
        print(json_out.dumps(public))
    else:
        print(format_text(public))
        if args.plot:
            print(f"plot: {args.plot}")
        if args.video:
            v = m["video"]
            print(f"video: {v['path']} ({v['frames']} frames at {v['fps']:g} fps, {v['bytes'] / 1024:.0f} kB, "
                  f"rendered in {v['render_s']:.1f} s)" + (f"; absent: {'; '.join(v['absent'])}" if v["absent"] else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
