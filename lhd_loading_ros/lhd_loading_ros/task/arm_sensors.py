"""The arm's angle sensors and the rates the Due reports from them (ROS-free).

On the machine the boom and bucket rates of the observation are not measured: the Arduino Due
differentiates the joint angles it samples (docs/serial_protocol.md, the sensor frame's boom_rate and
bucket_rate). A difference over one 10 ms sensor frame turns any noise on the angles into rate noise
of sqrt(2) sd / 0.01 s: 0.1 deg of noise (a potentiometer on a 12-bit ADC, about 1.4 counts of 300
deg) reads as 0.25 rad/s, more than the hydraulics' full speed (0.19-0.2 rad/s), and one count of a
4,096-count encoder as 0.15 rad/s. The firmware therefore differentiates over the last
RATE_WINDOW_S (one control period: the policy decides every 0.1 s and cannot use a faster rate):
sqrt(2) x 0.1 deg / 0.1 s = 0.025 rad/s (docs/training.md "The arm's rates"). The firmware's own
copy is lhd_hw_bridge/firmware/lhd_due/arm_rate.h; test/hw_bridge/test_arm_rate.py runs both on the
same samples.

:class:`RateWindow` is that difference; :func:`quantize` an encoder's counts; both are used by the
digital twin's device (lhd_sim_node/sim_due.py) and by the environment's sensor model
(Conditions.arm_angle_noise_deg, arm_encoder_counts).
"""
from __future__ import annotations

import math
from collections import deque

RATE_WINDOW_S = 0.1          # s: the firmware's rate window (arm_rate.h RATE_WINDOW_US)


def quantize(angle: float, counts: int) -> float:
    """The angle (rad) an encoder of `counts` counts per turn reads: the nearest count (0: exact)."""
    if counts <= 0:
        return float(angle)
    q = math.tau / counts
    return q * math.floor(angle / q + 0.5)


class RateWindow:
    """The rate of one joint over the last `window_s`: (newest angle - the angle `window_s` or more
    before it, the newest such sample) / the time between them. Until a sample that old exists, the
    oldest kept stands in (0 with one sample), as the firmware does after power-up. Samples must come
    in time order."""

    def __init__(self, window_s: float = RATE_WINDOW_S):
        if not (math.isfinite(window_s) and window_s > 0.0):
            raise ValueError(f"rate window {window_s!r} s: expected a positive number of seconds")
        self.window_s = float(window_s)
        self._samples: deque[tuple[float, float]] = deque()

    def reset(self) -> None:
        self._samples.clear()

    def push(self, t: float, angle: float) -> float:
        """Add the sample (t s, angle rad) and return the rate (rad/s) over the window ending at it."""
        s = self._samples
        if s and t <= s[-1][0]:
            raise ValueError(f"sample at {t!r} s is not after the last one at {s[-1][0]!r} s")
        s.append((float(t), float(angle)))
        # keep one sample at least window_s old, and none older than that one (1e-9: a float grid)
        while len(s) >= 2 and t - s[1][0] >= self.window_s - 1e-9:
            s.popleft()
        t0, a0 = s[0]
        return 0.0 if t == t0 else (angle - a0) / (t - t0)
