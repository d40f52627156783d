"""ros/stamps.py: the stamp checks the sensor nodes share, and the per-kind log throttle."""
from lhd_loading_ros.ros.stamps import FUTURE_TOLERANCE_S, KindThrottle, stamp_problem

NOW = 1_800_000_000 * 10 ** 9        # ns


def test_zero_and_future_stamps_are_named_and_a_past_one_passes():
    assert "scan stamp is zero: expected its acquisition time" in stamp_problem(0, 0, NOW, "scan")
    assert stamp_problem(1_800_000_000, 0, NOW, "scan") is None
    assert stamp_problem(1_799_999_000, 0, NOW, "scan") is None                  # old: the consumer judges it
    assert stamp_problem(1_800_000_000 + int(FUTURE_TOLERANCE_S), 0, NOW, "scan") is None    # at the tolerance
    msg = stamp_problem(1_800_000_003, 0, NOW, "image")
    assert msg.startswith("image stamp 1800000003.000 s is 3 s ahead of this node's clock (1800000000.000 s)")
    # a simulated clock not heard yet (0): only the zero check
    assert stamp_problem(12, 500, 0, "scan") is None and stamp_problem(0, 0, 0, "scan") is not None


def test_the_throttle_is_per_kind_of_message():
    t = [0.0]
    th = KindThrottle(5.0, clock=lambda: t[0])
    assert th.due("image 320x240 differs from CameraInfo's 640x480")
    assert not th.due("image 330x250 differs from CameraInfo's 640x480")      # same kind, other figures
    assert th.due("unsupported image encoding 'yuv422'")                       # another kind: logged
    t[0] = 5.0
    assert th.due("image 330x250 differs from CameraInfo's 640x480")           # a period later: again
    for k in range(200):                                                       # kinds are bounded
        th.due(f"kind {chr(65 + k % 26)}{chr(65 + k // 26)}")
    assert len(th.last) <= 65
