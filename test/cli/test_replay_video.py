"""`lhd replay BAG --video`: a GIF of a real bag written with rosbags (test_replay.py's attempt:
the machine driving and lifting for 1 s inside a 3.1 s bag), its frame count from the bag's
duration and the fps, its size, frames that change where the bucket moves, the same bytes twice,
the twin's FEE arrow and dug surface drawn when the bag has /lhd/twin/markers, and the MP4 path's
clear error without imageio-ffmpeg."""
import math
import sys

import numpy as np
import pytest
from PIL import Image

from lhd_loading_ros.cli import replay, replay_video

from test_replay import TS, T, attempt_messages, write_bag


def _frames(path):
    im = Image.open(path)
    out = []
    for k in range(im.n_frames):
        im.seek(k)
        out.append(np.asarray(im.convert("RGB"), dtype=np.int16))
    return out


def _twin_markers(t_ns, fee):
    """A MarkerArray as the twin sends it: one pile strip at y = 0 and the FEE arrow (or its DELETE)."""
    P, M = T["geometry_msgs/msg/Point"], T["visualization_msgs/msg/Marker"]
    hdr = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="pile")
    z0 = T["builtin_interfaces/msg/Duration"](sec=0, nanosec=0)

    def marker(ns, action, pts):
        return M(header=hdr, ns=ns, id=0, type=4, action=action,
                 pose=T["geometry_msgs/msg/Pose"](position=P(x=0.0, y=0.0, z=0.0),
                                                  orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0,
                                                                                               w=1.0)),
                 scale=T["geometry_msgs/msg/Vector3"](x=0.01, y=0.0, z=0.0),
                 color=T["std_msgs/msg/ColorRGBA"](r=1.0, g=0.0, b=0.0, a=1.0), lifetime=z0, frame_locked=False,
                 points=[P(x=x, y=0.0, z=z) for x, z in pts], colors=[], texture_resource="",
                 texture=T["sensor_msgs/msg/CompressedImage"](header=hdr, format="", data=np.zeros(0, np.uint8)),
                 uv_coordinates=[], text="", mesh_resource="",
                 mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
                 mesh_use_embedded_materials=False)
    surface = [(0.0, 0.0), (1.0, 0.3), (2.0, 0.55), (2.6, 0.55)]
    arr = T["visualization_msgs/msg/MarkerArray"](markers=[
        marker("pile", 0, surface), marker("fee", 0 if fee else 2, [(1.9, 0.1), (1.4, 0.2)] if fee else [])])
    return ("/lhd/twin/markers", t_ns, arr)


def test_a_gif_of_an_attempt(cfg, tmp_path, capsys):
    bag = write_bag(tmp_path / "bag", attempt_messages(cfg))
    gif = tmp_path / "v" / "a4.gif"
    assert replay.main([str(bag), "--video", str(gif), "--fps", "10"]) == 0
    text = capsys.readouterr().out
    assert "video: " in text and "absent: " in text and "FEE force (only the digital twin records it" in text
    frames = _frames(gif)
    # the bag spans 100 ns .. 3.1 s: floor(3.1 * 10) + 1 frames
    rec = replay.read_bag(bag)
    assert len(frames) == math.floor(rec.duration_s * 10 + 1e-6) + 1 == 32
    h, w, _ = frames[0].shape                  # 800 wide; the height follows the scene (equal x and z scales)
    assert w == 800 and 344 <= h <= 706 and h % 2 == 0, frames[0].shape
    assert 20_000 < gif.stat().st_size < 3_000_000
    # the machine moves between 2.0 s (k = 20) and 2.9 s (k = 29): the bucket (the yellow of the
    # boom and bucket) rises and moves right; before the first joint state (k < 20) no machine,
    # and those frames differ only in the title (attempt 3's success, then attempt 4 armed) and
    # the caption's time, not in the side view
    def yellow(f):
        ys, xs = np.nonzero(np.abs(f[:, :580] - np.array([229, 178, 25])).sum(axis=2) < 60)   # the side view, not the legend
        return len(xs), (xs.mean() if len(xs) else None), (ys.mean() if len(ys) else None)
    assert yellow(frames[15])[0] == 0
    n21, x21, y21 = yellow(frames[21])
    n29, x29, y29 = yellow(frames[29])
    assert n21 > 300 and n29 > 300, (n21, n29)
    assert x29 > x21 + 5 and y29 < y21 - 5, (x21, y21, x29, y29)      # right and up (pixel rows grow down)
    changed = np.abs(frames[5] - frames[15]).sum(axis=2) > 30     # not a palette shade
    assert changed[:40].any() and changed[h - 30:].any() and not changed[55:h - 60, :580].any()
    # deterministic (at 2 fps: 7 frames)
    a, b = tmp_path / "a.gif", tmp_path / "b.gif"
    assert replay.main([str(bag), "--video", str(a), "--fps", "2", "--json"]) == 0
    assert replay.main([str(bag), "--video", str(b), "--fps", "2", "--json"]) == 0
    assert a.read_bytes() == b.read_bytes() and len(_frames(a)) == 7


def test_the_twins_markers_draw_the_fee_arrow(cfg, tmp_path, capsys):
    msgs = attempt_messages(cfg) + [_twin_markers(2 * 10**9, True), _twin_markers(int(2.5 * 10**9), False)]
    bag = write_bag(tmp_path / "bag", msgs)
    gif = tmp_path / "t.gif"
    rec = replay.read_bag(bag, replay_video.EXTRA_TOPICS)
    mk = rec.extra["/twin/markers"].v
    assert mk[0]["fee"].tolist() == [[1.9, 0.1], [1.4, 0.2]] and mk[1]["fee"] is None
    assert mk[0]["pile"][-1].tolist() == [2.6, 0.55]
    assert replay.main([str(bag), "--video", str(gif), "--fps", "5"]) == 0
    assert "FEE force" not in capsys.readouterr().out.split("absent:")[-1]
    frames = _frames(gif)
    side = [f[:, :580] for f in frames]                                      # the side view, not the legend
    magenta = [((f[:, :, 0] > 180) & (f[:, :, 1] < 80) & (f[:, :, 2] > 180)).sum() for f in side]
    assert magenta[11] > 50 and magenta[14] == magenta[5] == 0, magenta    # drawn at 2.2 s, deleted by 2.8 s


def test_mp4_without_imageio_ffmpeg_and_bad_names(cfg, tmp_path, capsys, monkeypatch):
    bag = write_bag(tmp_path / "bag", attempt_messages(cfg))
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)        # import imageio_ffmpeg -> ImportError
    assert replay.main([str(bag), "--video", str(tmp_path / "a.mp4")]) == 2
    err = capsys.readouterr().err
    assert "MP4 needs the Python package imageio-ffmpeg" in err and f"--video {tmp_path / 'a.gif'}" in err
    assert not (tmp_path / "a.mp4").exists()
    assert replay.main([str(bag), "--video", str(tmp_path / "a.avi")]) == 2
    assert "expected a .gif or .mp4" in capsys.readouterr().err
    assert replay.main([str(bag), "--video", str(tmp_path / "a.gif"), "--fps", "0"]) == 2
    assert "--fps 0" in capsys.readouterr().err
    # --plot's format too, before the bag is read (matplotlib's refusal was a traceback: a review)
    assert replay.main([str(bag), "--plot", str(tmp_path / "a.txt")]) == 2
    assert "--plot" in (err := capsys.readouterr().err) and ".png" in err and not (tmp_path / "a.txt").exists()
    with pytest.raises(replay_video.VideoError, match="at most"):
        replay_video.frame_times(0, 1e6, 10.0)
