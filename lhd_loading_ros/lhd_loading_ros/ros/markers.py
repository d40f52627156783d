"""visualization_msgs/MarkerArray for RViz and Foxglove, shared by the digital twin
(lhd_sim_node.twin_markers: the pile's surface, the zones, the bucket tip's trajectory and the
FEE force) and the supervisor (nodes/supervisor_node.py: the zones and the running attempt's tip
trajectory), from the plain arrays of task/viz.py (zone_boxes, TipTrail.array) and
lhd_sim_node.sim_sensors (pile_surfaces, fee_arrow).

Every marker has a fixed (namespace, id), so each array replaces the previous one in the viewer;
a part with nothing to show (no zones yet, the bucket out of the pile) is sent as a DELETE of its
id, so a stale arrow never lingers. Poses are identity except the zone boxes' centres; every
number is finite (non-finite points are dropped, a part left with too few is deleted). The same
namespaces and colours everywhere: pile (brown strips), zones (end green, permitted blue,
cutoff red), tip (orange), fee (magenta).
"""
from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

NS_PILE, NS_ZONES, NS_TIP, NS_FEE = "pile", "zones", "tip", "fee"
MAX_SLICES = 64                  # ids reserved for pile surface strips
ZONE_COLORS = {"end": (0.1, 0.8, 0.2, 0.35), "permitted": (0.2, 0.4, 1.0, 0.12), "cutoff": (1.0, 0.1, 0.1, 0.5)}
ZONE_IDS = {"end": 0, "permitted": 1, "cutoff": 2}
TIP_COLOR = (1.0, 0.6, 0.0, 1.0)
FEE_COLOR = (0.9, 0.1, 0.9, 1.0)
PILE_COLOR = (0.55, 0.4, 0.25, 1.0)


def _color(r, g, b, a) -> ColorRGBA:
    return ColorRGBA(r=float(r), g=float(g), b=float(b), a=float(a))


def _points(arr) -> list[Point]:
    a = np.asarray(arr, dtype=float).reshape(-1, 3)
    a = a[np.isfinite(a).all(axis=1)]
    return [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in a]


def _base(stamp, frame_id: str, ns: str, mid: int, mtype: int) -> Marker:
    m = Marker()
    m.header.stamp = stamp
    m.header.frame_id = frame_id
    m.ns, m.id, m.type, m.action = ns, int(mid), mtype, Marker.ADD
    m.pose.orientation.w = 1.0
    m.lifetime = Duration(sec=0, nanosec=0)       # until replaced
    m.frame_locked = False
    return m


def _delete(stamp, frame_id: str, ns: str, mid: int) -> Marker:
    m = _base(stamp, frame_id, ns, mid, Marker.ARROW)
    m.action = Marker.DELETE
    m.scale.x = m.scale.y = m.scale.z = 1.0         # well formed even for viewers that check
    m.color = _color(0, 0, 0, 0)
    return m


def delete_all(stamp, frame_id: str) -> Marker:
    """A DELETEALL (every marker of this topic, all namespaces): the first marker of an array
    that starts afresh (the supervisor's at a new attempt)."""
    m = _delete(stamp, frame_id, "", 0)
    m.action = Marker.DELETEALL
    return m


def zone_markers(stamp, frame_id: str, boxes) -> list[Marker]:
    """boxes: list of (name, centre, size) (task.viz.zone_boxes): one translucent CUBE each
    (ns zones, ids ZONE_IDS, the name as text); a missing or degenerate box is a DELETE."""
    out = []
    named = {name: (c, s) for name, c, s in (boxes or [])}
    for name, mid in ZONE_IDS.items():
        if name not in named:
            out.append(_delete(stamp, frame_id, NS_ZONES, mid))
            continue
        c, s = (np.asarray(v, dtype=float).reshape(3) for v in named[name])
        if not (np.isfinite(c).all() and np.isfinite(s).all() and (s > 0).all()):
            out.append(_delete(stamp, frame_id, NS_ZONES, mid))
            continue
        m = _base(stamp, frame_id, NS_ZONES, mid, Marker.CUBE)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in c)
        m.scale.x, m.scale.y, m.scale.z = (float(v) for v in s)
        m.color = _color(*ZONE_COLORS[name])
        m.text = name
        out.append(m)
    return out


def tip_marker(stamp, frame_id: str, tip_trail, line_width: float = 0.008) -> Marker:
    """tip_trail: (n, 3) points (TipTrail.array): a LINE_STRIP (ns tip, id 0), a DELETE below 2 points."""
    pts = _points(tip_trail) if tip_trail is not None else []
    if len(pts) < 2:
        return _delete(stamp, frame_id, NS_TIP, 0)
    m = _base(stamp, frame_id, NS_TIP, 0, Marker.LINE_STRIP)
    m.scale.x = line_width
    m.color = _color(*TIP_COLOR)
    m.points = pts
    return m


def supervisor_markers(stamp, frame_id: str, boxes, tip_trail, clear: bool = False,
                       line_width: float = 0.008) -> MarkerArray:
    """The supervisor's array: [DELETEALL when `clear`], the zone boxes (ns zones), the running
    attempt's tip trajectory (ns tip) - always whole, so the latched last array is the picture."""
    if not (line_width > 0 and math.isfinite(line_width)):
        raise ValueError(f"line_width = {line_width!r}: expected a positive number of metres")
    out = MarkerArray()
    if clear:
        out.markers.append(delete_all(stamp, frame_id))
    out.markers.extend(zone_markers(stamp, frame_id, boxes))
    out.markers.append(tip_marker(stamp, frame_id, tip_trail, line_width))
    return out


def marker_array(stamp, frame_id: str = "pile", surfaces=None, boxes=None, tip_trail=None, fee=None,
                 line_width: float = 0.008) -> MarkerArray:
    """The twin's markers at `stamp` (builtin_interfaces/Time) in `frame_id`.

    surfaces: list of (n, 3) polylines (sim_sensors.pile_surfaces), one LINE_STRIP each (ns pile);
    boxes: list of (name, centre, size) (task.viz.zone_boxes), one translucent CUBE each (ns zones);
    tip_trail: (n, 3) points (TipTrail.array), a LINE_STRIP (ns tip, id 0);
    fee: (2, 3) start and end (sim_sensors.fee_arrow) or None, an ARROW (ns fee, id 0).
    None or empty parts are DELETEs of their ids."""
    if not (line_width > 0 and math.isfinite(line_width)):
        raise ValueError(f"line_width = {line_width!r}: expected a positive number of metres")
    out = MarkerArray()
    surfaces = list(surfaces or [])
    if len(surfaces) > MAX_SLICES:
        raise ValueError(f"{len(surfaces)} pile surface strips: at most {MAX_SLICES}")
    for j in range(MAX_SLICES):
        pts = _points(surfaces[j]) if j < len(surfaces) else []
        if len(pts) < 2:
            if j < len(surfaces) or j == 0:
                out.markers.append(_delete(stamp, frame_id, NS_PILE, j))
            continue
        m = _base(stamp, frame_id, NS_PILE, j, Marker.LINE_STRIP)
        m.scale.x = line_width
        m.color = _color(*PILE_COLOR)
        m.points = pts
        out.markers.append(m)
    out.markers.extend(zone_markers(stamp, frame_id, boxes))
    out.markers.append(tip_marker(stamp, frame_id, tip_trail, line_width))
    pts = _points(fee) if fee is not None else []
    if len(pts) == 2:
        m = _base(stamp, frame_id, NS_FEE, 0, Marker.ARROW)
        m.scale.x, m.scale.y, m.scale.z = 0.02, 0.04, 0.06     # shaft diameter, head diameter, head length
        m.color = _color(*FEE_COLOR)
        m.points = pts
        out.markers.append(m)
    else:
        out.markers.append(_delete(stamp, frame_id, NS_FEE, 0))
    return out
