"""Sanity of a sensor message's header stamp, and log lines throttled per kind of problem.

A sensor's stamp is its acquisition time, and consumers judge a measurement's age by it: a zero
stamp (a driver that does not stamp) makes every age meaningless, and a stamp ahead of this
computer's clock makes a measurement look fresh for as long as it is ahead (a LiDAR slope stamped
1e6 s ahead would never look stale). Both are refused. A stamp behind the previous one is a bag
loop or a driver restart: the callers restart what depends on time order and say so.
"""
from __future__ import annotations

import re
import time

# s a stamp may be ahead of the node's clock (clock skew, a sim clock one step behind). A bag
# replayed with `ros2 bag play --clock --rate R` publishes /clock at 40 Hz by default: above R = 80
# a clock step exceeds this and messages between two steps are refused; raise --clock's rate then.
FUTURE_TOLERANCE_S = 2.0


def stamp_problem(sec: int, nanosec: int, now_ns: int, what: str) -> str | None:
    """Why the stamp (sec, nanosec) of `what` cannot be used, or None. `now_ns`: the node's clock
    (ROS time; 0 while a simulated clock has not been heard, when only the zero check applies)."""
    t_ns = int(sec) * 1_000_000_000 + int(nanosec)
    if t_ns <= 0:
        return f"{what} stamp is zero: expected its acquisition time (the driver must stamp its messages)"
    if now_ns > 0 and t_ns - now_ns > FUTURE_TOLERANCE_S * 1e9:
        return (f"{what} stamp {t_ns / 1e9:.3f} s is {(t_ns - now_ns) / 1e9:.3g} s ahead of this node's clock "
                f"({now_ns / 1e9:.3f} s); expected its acquisition time, at most {FUTURE_TOLERANCE_S:g} s ahead "
                "(is the sensor's clock synchronised with this computer's, and use_sim_time the same on both?)")
    return None


class KindThrottle:
    """Log a message unless one of the same kind was logged within `period` s. The kind is the
    message with its numbers masked, so two different problems are both logged (rclpy throttles
    per call site: one problem hid another for 5 s), and one problem with changing figures is not
    logged at every message."""

    _NUM = re.compile(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?")

    def __init__(self, period: float = 5.0, clock=time.monotonic):
        self.period, self.clock = float(period), clock
        self.last: dict[str, float] = {}

    def kind(self, msg: str) -> str:
        return self._NUM.sub("#", msg)

    def due(self, msg: str) -> bool:
        k, now = self.kind(msg), self.clock()
        if now - self.last.get(k, -float("inf")) < self.period:
            return False
        self.last[k] = now
        if len(self.last) > 64:                   # kinds are few; never grows without bound
            oldest = min(self.last, key=self.last.get)
            del self.last[oldest]
        return True
