"""task/transition.py: the learner's transition message, exact in float64, and its checks."""
import numpy as np
import pytest

from lhd_loading_ros.task import transition as tr


def test_round_trip_is_exact():
    obs = np.array([0.1, -0.2, 0.3, 0.4, -0.5, 1.0, 0.7, -0.8, 0.9, -1.0, 0.0, 0.25], dtype=np.float32)
    data = tr.encode(3, 2**31 - 2, 17, 123_456_789_012_345, -12.5, True, False, obs, (2.7, -0.35, 0.5))
    assert len(data) == tr.SIZE == 22
    t = tr.decode(data)
    assert (t.episode, t.seed, t.step, t.stamp_ns) == (3, 2**31 - 2, 17, 123_456_789_012_345)
    assert t.reward == -12.5 and t.terminated and not t.truncated
    assert t.obs.dtype == np.float32 and np.array_equal(t.obs, obs)      # bit for bit
    assert t.command.tolist() == [2.7, -0.35, 0.5]
    assert tr.LABEL.startswith("episode,seed,step,stamp_ns,reward,terminated,truncated")


@pytest.mark.parametrize("bad, why", [
    ([0.0] * 19, "expected 22"),
    ([0.5] + [0.0] * 21, "non-negative integers"),
    ([-1.0] + [0.0] * 21, "non-negative integers"),
    ([0.0] * 5 + [0.5] + [0.0] * 16, "0 or 1"),
    ([0.0] * 7 + [float("nan")] + [0.0] * 14, "non-finite"),
])
def test_decode_refuses(bad, why):
    with pytest.raises(ValueError, match=why):
        tr.decode(bad)


def test_encode_refuses_what_cannot_be_carried():
    with pytest.raises(ValueError, match="expected 12"):
        tr.encode(0, 0, 0, 0, 0.0, False, False, np.zeros(11))
    with pytest.raises(ValueError, match="not finite"):
        tr.encode(0, 0, 0, 0, float("inf"), False, False, np.zeros(12))
    with pytest.raises(ValueError, match="command"):
        tr.encode(0, 0, 0, 0, 0.0, False, False, np.zeros(12), (0.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match="2\\^53"):
        tr.encode(0, 0, 0, 2**53, 0.0, False, False, np.zeros(12))
