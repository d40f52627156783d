"""`lhd replay BAG --video OUT.gif|OUT.mp4 [--fps 10]`: an attempt's side view, animated from its bag.

One frame every 1/fps s of bag time, from the bag's first message to its last (frames =
floor(duration * fps) + 1), each showing what the bag held at that time (the latest message at
or before it):
* the pile: the dug surface of the digital twin's markers (<prefix>/twin/markers, ns `pile`, the
  strip nearest y = 0) when the bag has them, else the intact face from pile/slope and the toe
  (pile/toe, else pile/zones, else x = 0), as `--plot` draws it;
* the zones from pile/zones (end zone green, permitted zone blue, cutoff red; restricted beyond),
  else the end zone of pile/end_zone;
* the machine (chassis boxes, wheels, boom, bucket; task/viz.py machine_outline) from odom and
  joint_states, the bucket tip's trail so far (orange; grey before the attempt ran);
* the FEE force on the bucket (magenta, 0.5 m per kN, the twin's ns `fee` arrow) when the bag has
  the twin's markers;
* a caption: time, attempt and its state, the loaded mass (episode status, else the twin's
  <prefix>/twin/truth/loaded_mass).
What the bag lacks is said in the legend ("absent: ...") and returned in `absent`.

Written with matplotlib's Agg canvas (no display, no pyplot state) into RGB frames: GIF with
Pillow (always there), MP4 (H.264) with imageio-ffmpeg when it is installed. The same bag gives
the same bytes.
"""
from __future__ import annotations

import bisect
import math
import time
from pathlib import Path

import numpy as np

from lhd_loading_ros.task.kinematics import ArmKinematics
from lhd_loading_ros.task.params import TaskParams
from lhd_loading_ros.task.replay import ODOM_GAP_S, Series, pile_toe_x
from lhd_loading_ros.task.viz import machine_outline, pile_face

FIG_W, DPI = 8.0, 100                  # 800 pixels wide; the height follows the scene (equal scales)
AX_LEFT, AX_W = 0.56, 5.28             # the side view's left edge and width, inches
AX_BOTTOM, AX_TOP_MARGIN = 0.55, 0.5   # below it the axis label and caption, above it the title
AX_H_RANGE = (2.4, 6.0)                # the side view's height, inches
FORMATS = (".gif", ".mp4")
FPS_RANGE = (0.5, 60.0)
MAX_FRAMES = 6000
TIP = (1.0, 0.6, 0.0)                  # the colours of ros/markers.py (RViz and the video agree)
FEE = (0.9, 0.1, 0.9)
PILE = (0.55, 0.4, 0.25)
ZONE = {"end": (0.1, 0.8, 0.2), "permitted": (0.2, 0.4, 1.0), "cutoff": (1.0, 0.1, 0.1)}
FEE_M_PER_N = 0.0005                   # the twin's arrow scale (sim_sensors.fee_arrow)


class VideoError(Exception):
    """The video cannot be written: a message for the user."""


def _markers(msg) -> dict:
    """The twin's MarkerArray reduced to what the side view needs: the FEE arrow's start and end
    in XZ (None when deleted) and the pile strip nearest y = 0 as (n, 2) XZ (None if absent)."""
    out = {}
    strips = []
    for m in msg.markers:
        if m.ns == "fee" and m.id == 0:
            pts = [(p.x, p.z) for p in m.points]
            out["fee"] = np.array(pts, float) if m.action == 0 and len(pts) == 2 else None
        elif m.ns == "pile" and m.action == 0 and len(m.points) >= 2:
            strips.append(m)
    if strips:
        mid = min(strips, key=lambda m: abs(sum(p.y for p in m.points) / len(m.points)))
        a = np.array([(p.x, p.z) for p in mid.points], float)
        out["pile"] = a[np.isfinite(a).all(axis=1)]
    return out


def _finite(m) -> float:
    v = float(m.data)
    if not math.isfinite(v):
        raise ValueError("not finite")
    return v


EXTRA_TOPICS = {"/twin/markers": _markers, "/twin/truth/loaded_mass": _finite}


def check_output(path: Path, fps: float) -> str | None:
    """Why `path` / `fps` cannot be used, before the bag is read (None when they can)."""
    if path.suffix.lower() not in FORMATS:
        return f"--video {path}: expected a .gif or .mp4 file name"
    if not (math.isfinite(fps) and FPS_RANGE[0] <= fps <= FPS_RANGE[1]):
        return f"--fps {fps:g}: expected {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g} frames per second"
    if path.suffix.lower() == ".mp4":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            return (f"--video {path}: MP4 needs the Python package imageio-ffmpeg (pip install imageio-ffmpeg), "
                    f"which is not installed; write a GIF instead: --video {path.with_suffix('.gif')}")
    return None


def frame_times(start_ns: int, duration_s: float, fps: float) -> list[int]:
    n = int(math.floor(max(duration_s, 0.0) * fps + 1e-6)) + 1
    if n > MAX_FRAMES:
        raise VideoError(f"{n} frames ({duration_s:.1f} s at {fps:g} fps): at most {MAX_FRAMES}; lower --fps")
    return [start_ns + round(k * 1e9 / fps) for k in range(n)]


def _latest(series: Series | None, t: int):
    if series is None or not len(series):
        return None
    s = series.latest_at(t)
    return s[1] if s else None


def _pose_at(rec, t: int):
    """(base position, quaternion, joints) at t: the latest joint state, the odometry nearest it."""
    js = rec.joints.latest_at(t)
    if js is None:
        return None
    od = rec.odom.latest_at(t) or rec.odom.nearest(js[0], int(ODOM_GAP_S * 1e9))
    if od is None or "boom" not in js[1] or "bucket" not in js[1]:
        return None
    return od[1][0], od[1][1], js[1]


def _status_at(rec, t: int) -> dict:
    return _latest(rec.status, t) or {}


def _mass_at(rec, t: int) -> tuple[float | None, str]:
    st = _status_at(rec, t)
    try:
        v = float(st.get("loaded_mass", "nan"))
    except ValueError:
        v = math.nan
    if math.isfinite(v):
        return v, "status"
    twin = _latest(rec.extra.get("/twin/truth/loaded_mass"), t)
    return (twin, "twin truth") if twin is not None else (None, "")


def _limits(m: dict, rec, kin, mc, p) -> tuple[float, float, float, float]:
    xs, zs = [], [0.0, p.h_pile]
    for s in m["_track"]:
        xs.append(s.x)
        zs.append(s.z)
    for pos, _, _ in rec.odom.v:
        xs.append(pos[0] - 0.35)
    pile = m["pile"]
    if pile["slope_deg"] is not None:
        xs.append(pile["toe_x"] + p.h_pile / math.tan(math.radians(pile["slope_deg"])))
    for z in rec.zones.v:
        xs += [z[0], z[1], z[3]]
    for ez in rec.end_zone.v:
        xs += [ez[0], ez[1]]
    for mk in rec.extra.get("/twin/markers", Series()).v:
        if mk.get("pile") is not None and len(mk["pile"]):
            xs += [float(np.nanmin(mk["pile"][:, 0])), float(np.nanmax(mk["pile"][:, 0]))]
    xs = [x for x in xs if math.isfinite(x)] or [0.0, 2.0]
    zs = [z for z in zs if math.isfinite(z)]
    left, right = min(xs) - 0.15, max(xs) + 0.2
    return left, right, -0.12, max(max(zs) + 0.45, 0.9)


def render(m: dict, rec, cfg: dict, out: Path, fps: float = 10.0) -> dict:
    """Write the animation of analysed bag `m` (cli/replay.analyse) to `out`; returns
    {path, frames, fps, bytes, render_s, absent}."""
    problem = check_output(out, fps)
    if problem:
        raise VideoError(problem)
    t_begin = time.perf_counter()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, FancyArrowPatch, Polygon, Rectangle

    p = TaskParams.from_config(cfg)
    mc = cfg["machine"]
    kin = ArmKinematics.from_config(cfg)
    w, track = m["_window"], m["_track"]
    times = frame_times(rec.start_ns, rec.duration_s, fps)
    markers = rec.extra.get("/twin/markers", Series())
    has_fee = any("fee" in v for v in markers.v)
    has_surface = any(v.get("pile") is not None for v in markers.v)
    pre = rec.prefix
    absent = []
    if not len(rec.odom) or not len(rec.joints):
        absent.append(f"machine and tip ({pre}/odom and {pre}/joint_states needed)")
    if not has_surface and not len(rec.slope):
        absent.append(f"pile ({pre}/pile/slope or the twin's markers)")
    if not len(rec.zones) and not len(rec.end_zone):
        absent.append(f"zones ({pre}/pile/zones or {pre}/pile/end_zone)")
    elif not len(rec.zones):
        absent.append(f"permitted zone and cutoff ({pre}/pile/zones)")
    if not has_fee:
        absent.append(f"FEE force (only the digital twin records it: {pre}/twin/markers)")
    if not len(rec.status):
        absent.append(f"attempt state ({pre}/episode)")

    left, right, bottom, top = _limits(m, rec, kin, mc, p)
    ax_h = min(max(AX_W * (top - bottom) / (right - left), AX_H_RANGE[0]), AX_H_RANGE[1])
    ratio = ax_h / AX_W                                             # height / width of the side view
    if (top - bottom) < ratio * (right - left):                   # equal scales: grow the short side
        top = bottom + ratio * (right - left)
    else:
        mid, half = (left + right) / 2, (top - bottom) / ratio / 2
        left, right = mid - half, mid + half
    fig_h = 2 * round((ax_h + AX_BOTTOM + AX_TOP_MARGIN) * DPI / 2) / DPI    # an even number of pixels (H.264)
    fig = Figure(figsize=(FIG_W, fig_h), dpi=DPI)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((AX_LEFT / FIG_W, AX_BOTTOM / fig_h, AX_W / FIG_W, ax_h / fig_h))
    ax.set_xlim(left, right)
    ax.set_ylim(bottom, top)
    ax.set_xlabel("x in the pile frame (m)", fontsize=8)
    ax.set_ylabel("z (m)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.axhline(0.0, color="0.3", lw=1)
    pile_poly = ax.add_patch(Polygon(np.zeros((3, 2)), closed=True, facecolor=PILE + (0.45,), edgecolor=PILE, lw=1))
    end_rect = ax.add_patch(Rectangle((0, 0), 0, 0, facecolor=ZONE["end"] + (0.25,), edgecolor=ZONE["end"], lw=1))
    perm_rect = ax.add_patch(Rectangle((0, 0), 0, 0, facecolor=ZONE["permitted"] + (0.08,),
                                       edgecolor=ZONE["permitted"] + (0.6,), lw=0.8, ls="--"))
    cutoff_line = Line2D([], [], color=ZONE["cutoff"], ls="--", lw=1.2)
    ax.add_line(cutoff_line)
    pre_trail = Line2D([], [], color="0.55", lw=1.2)
    trail = Line2D([], [], color=TIP, lw=2.0)
    ax.add_line(pre_trail)
    ax.add_line(trail)
    rear = ax.add_patch(Polygon(np.zeros((4, 2)), closed=True, facecolor="0.85", edgecolor="0.2", lw=1))
    front = ax.add_patch(Polygon(np.zeros((4, 2)), closed=True, facecolor="0.85", edgecolor="0.2", lw=1))
    wheels = [ax.add_patch(Circle((0, 0), mc["wheel_radius"], facecolor="0.15", edgecolor="0.0")) for _ in range(2)]
    boom = Line2D([], [], color=(0.9, 0.7, 0.1), lw=5, solid_capstyle="round")
    ax.add_line(boom)
    bucket = ax.add_patch(Polygon(np.zeros((4, 2)), closed=True, facecolor=(0.9, 0.7, 0.1), edgecolor="0.2", lw=1))
    tip_dot = Line2D([], [], marker="o", color=TIP, ms=4, ls="")
    ax.add_line(tip_dot)
    arrow = ax.add_patch(FancyArrowPatch((0, 0), (0, 0), arrowstyle="-|>", mutation_scale=14, color=FEE, lw=2))
    title = fig.text(AX_LEFT / FIG_W, 1 - 0.3 / fig_h, "", fontsize=10, weight="bold")
    caption = fig.text(AX_LEFT / FIG_W, 0.06 / fig_h, "", fontsize=8, family="monospace")
    machine_parts = [rear, front, *wheels, bucket]

    handles = [Polygon(np.zeros((3, 2)), facecolor=PILE + (0.45,), edgecolor=PILE,
                       label="pile (twin's dug surface)" if has_surface else "pile face (slope, toe)"),
               Rectangle((0, 0), 1, 1, facecolor=ZONE["end"] + (0.25,), edgecolor=ZONE["end"], label="end zone"),
               Rectangle((0, 0), 1, 1, facecolor=ZONE["permitted"] + (0.08,), edgecolor=ZONE["permitted"], ls="--",
                         label="permitted zone"),
               Line2D([], [], color=ZONE["cutoff"], ls="--", label="cutoff (restricted beyond)"),
               Line2D([], [], color=TIP, lw=2, label="bucket tip (attempt)"),
               Line2D([], [], color="0.55", lw=1.2, label="bucket tip (before)"),
               Polygon(np.zeros((3, 2)), facecolor=(0.9, 0.7, 0.1), edgecolor="0.2", label="machine, bucket")]
    if has_fee:
        handles.append(Line2D([], [], color=FEE, lw=2, label=f"FEE force ({FEE_M_PER_N * 1000:g} m/kN)"))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.745, 1 - AX_TOP_MARGIN / fig_h), fontsize=7, frameon=False)
    if absent:
        fig.text(0.755, AX_BOTTOM / fig_h, "absent from the bag:\n" + "\n".join(_wrap(a, 34) for a in absent), fontsize=6.5,
                 va="bottom", color="0.35")

    tip_t = [s.t for s in track]
    t_run = w.t_start

    def frame(t: int) -> np.ndarray:
        # pile: the twin's surface, else the face from slope and toe
        mk = _latest(markers, t) or {}
        surface = mk.get("pile")
        if surface is not None and len(surface) >= 2:
            pile_poly.set_xy(np.vstack([surface, [[surface[-1, 0], 0.0], [surface[0, 0], 0.0]]]))
            pile_poly.set_visible(True)
        else:
            slope = _latest(rec.slope, t)
            face = None
            if slope is not None:
                zones = _latest(rec.zones, t)
                toe = _latest(rec.toe, t)
                face = pile_face(slope, pile_toe_x(zones, toe, p.x_init_obs)[0], p.h_pile, right + 1.0)
            pile_poly.set_visible(face is not None)
            if face is not None:
                pile_poly.set_xy(face)
        zones = _latest(rec.zones, t)
        ez = zones[:3] if zones is not None else _latest(rec.end_zone, t)
        end_rect.set_visible(ez is not None)
        if ez is not None:
            end_rect.set_bounds(ez[0], ez[2], ez[1] - ez[0], top - ez[2])
        perm_rect.set_visible(zones is not None)
        cutoff_line.set_visible(zones is not None)
        if zones is not None:
            x0, x1 = zones[4], min(zones[5], zones[3])
            perm_rect.set_bounds(x0, 0.0, x1 - x0, zones[7])
            cutoff_line.set_data([zones[3], zones[3]], [0.0, top])
        # tip trail up to t: grey before the attempt ran, orange from then on
        n = bisect.bisect_right(tip_t, t)
        done = track[:n]
        k = min(bisect.bisect_left(tip_t, t_run) if t_run is not None else 0, n)
        before, during = done[: min(k + 1, n)], done[k:]        # the grey line meets the orange one
        pre_trail.set_data([s.x for s in before], [s.z for s in before])
        trail.set_data([s.x for s in during], [s.z for s in during])
        # machine
        pose = _pose_at(rec, t)
        shown = False
        if pose is not None:
            pos, quat, js = pose
            try:
                o = machine_outline(kin, mc, pos, quat, js["boom"][0], js["bucket"][0],
                                    js.get("articulation", (0.0, 0.0))[0])
                shown = all(np.isfinite(o[k]).all() for k in ("rear_body", "front_body", "boom", "bucket"))
            except (ValueError, TypeError):
                shown = False
            if shown:
                rear.set_xy(o["rear_body"])
                front.set_xy(o["front_body"])
                for c, (x, z, r) in zip(wheels, o["wheels"]):
                    c.set_center((x, z))
                boom.set_data(o["boom"][:, 0], o["boom"][:, 1])
                bucket.set_xy(o["bucket"])
                tip_dot.set_data([o["tip"][0]], [o["tip"][1]])
        for a in machine_parts + [boom, tip_dot]:
            a.set_visible(shown)
        fee = mk.get("fee")
        arrow.set_visible(fee is not None)
        if fee is not None:
            arrow.set_positions(tuple(fee[0]), tuple(fee[1]))
        # caption
        st = _status_at(rec, t)
        state = st.get("state", "-")
        att = st.get("episode", "?")
        mass, source = _mass_at(rec, t)
        t_rel = (t - rec.start_ns) / 1e9
        since = f", {(t - t_run) / 1e9:+.1f} s from running" if t_run is not None else ""
        title.set_text(f"attempt {m['attempt'] if m['attempt'] is not None else att}: {state}"
                       + (f" ({m['outcome']} at the end)" if m.get("outcome") and state != m["outcome"] else ""))
        force = f", FEE {np.linalg.norm(fee[1] - fee[0]) / FEE_M_PER_N:.0f} N (xz)" if fee is not None else ""
        caption.set_text(f"t {t_rel:6.2f} s{since}   loaded mass "
                         + (f"{mass:.2f} kg ({source})" if mass is not None else "-") + force)
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()

    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() == ".gif":
        from PIL import Image

        # one palette for every frame (no shimmer of the shades from frame to frame): median cut of
        # four frames spread over the bag and swatches of the drawing's colours
        sample = [frame(times[round(i * (len(times) - 1) / 3)]) for i in range(4)]
        swatch = np.zeros((8, sample[0].shape[1], 3), np.uint8)
        for i, c in enumerate((TIP, FEE, PILE, *ZONE.values())):
            swatch[:, i * 40:(i + 1) * 40] = np.array(c) * 255
        palette = Image.fromarray(np.vstack(sample + [swatch])).quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                                                                          dither=Image.Dither.NONE)
        images = [Image.fromarray(frame(t)).quantize(palette=palette, dither=Image.Dither.NONE) for t in times]
        images[0].save(out, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0,
                       optimize=False, disposal=1)
    else:
        import imageio_ffmpeg

        first = frame(times[0])
        h, wpx = first.shape[:2]
        writer = imageio_ffmpeg.write_frames(str(out), (wpx, h), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
                                             macro_block_size=2, ffmpeg_log_level="error",
                                             output_params=["-fflags", "+bitexact", "-flags:v", "+bitexact"])
        writer.send(None)
        try:
            writer.send(np.ascontiguousarray(first))
            for t in times[1:]:
                writer.send(np.ascontiguousarray(frame(t)))
        finally:
            writer.close()
    return {"path": str(out), "frames": len(times), "fps": fps, "bytes": out.stat().st_size,
            "render_s": time.perf_counter() - t_begin, "absent": absent}


def _wrap(text: str, width: int) -> str:
    words, lines, cur = text.split(), [], ""
    for w_ in words:
        if cur and len(cur) + 1 + len(w_) > width:
            lines.append(cur)
            cur = "  " + w_
        else:
            cur = f"{cur} {w_}" if cur else w_
    return "\n".join(lines + [cur])
