"""When the recorder opens and closes an attempt's bag, where the bag goes, and which topics it
records (ROS-free; the recorder node, nodes/recorder_node.py, is a thin shell over this).

The attempt's life cycle comes from `<prefix>/episode` (diagnostic_msgs/DiagnosticStatus, key
`state`, key `episode` = the attempt number):

* armed or running -> a bag for that attempt opens (running too, in case armed was missed:
  a recorder started during an attempt still records the rest of it);
* any end state (success, failure, timeout, estop, lost_input, aborted), or idle, or a status
  of another attempt -> the bag closes `post_roll_s` later (the zero command after the end,
  the machine coming to rest); a new attempt armed during the post-roll closes it at once.

The status topic is reliable + transient local with a history (STATUS_QOS): a recorder that
subscribes late first receives up to ten old statuses in a burst, e.g. armed 3, running 3,
success 3, armed 4. Opening a bag on the first of them would record an attempt that is over.
So an open waits SETTLE_S: an end of the same attempt inside that window cancels it. A real
armed state lasts far longer (the supervisor's arm_delay, 1 s by default, before running).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

ACTIVE_STATES = ("armed", "running")
END_STATES = ("success", "failure", "timeout", "estop", "lost_input", "aborted")
IDLE_STATE = "idle"
SETTLE_S = 0.1      # an open waits this long for a later status of a history burst to cancel it


def attempt_number(values: dict) -> int | None:
    """The attempt number in a status's key/values (`episode`), or None when absent or not a
    whole number >= 0 ("3", "3.0" and 3 are attempt 3)."""
    raw = values.get("episode")
    if raw is None:
        return None
    try:
        v = float(raw)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(v) or v < 0 or not v.is_integer():
        return None
    return int(v)


def bag_name(attempt: int) -> str:
    """bags/attempt_NNNN: the attempt number zero-padded to 4 digits (more digits past 9999)."""
    if attempt < 0:
        raise ValueError(f"attempt number {attempt}: expected a whole number >= 0")
    return f"attempt_{attempt:04d}"


def bag_folder(run_dir, attempt: int) -> tuple[Path, str | None]:
    """(the folder for the attempt's bag, a note when it is not the plain name).

    <run_dir>/bags/attempt_NNNN, or, when that already exists (a restarted supervisor that
    reused a number, a second recorder), the first free attempt_NNNN_2, _3, ...: an existing
    bag is never overwritten."""
    bags = Path(run_dir) / "bags"
    base = bags / bag_name(attempt)
    if not base.exists():
        return base, None
    k = 2
    while (bags / f"{base.name}_{k}").exists():
        k += 1
    path = bags / f"{base.name}_{k}"
    return path, (f"{base} already exists (a restarted supervisor reused attempt {attempt}?): it is kept, "
                  f"this attempt is recorded into {path.name}")


def next_free_attempt(run_dir) -> int:
    """1 + the highest attempt number among <run_dir>/bags/attempt_NNNN* (1 when none): the
    number given to an attempt whose status carries no usable `episode` key."""
    best = 0
    bags = Path(run_dir) / "bags"
    if bags.is_dir():
        for p in bags.iterdir():
            head = p.name.split("_")
            if len(head) >= 2 and head[0] == "attempt" and head[1].isdigit():
                best = max(best, int(head[1]))
    return best + 1


def topic_selected(topic: str, prefix: str, extra: tuple | list = ()) -> bool:
    """Every topic under the prefix (the prefix itself too), and the extra absolute topics."""
    p = prefix.rstrip("/")
    return topic == p or topic.startswith(p + "/") or topic in extra


@dataclass
class Action:
    kind: str           # "open" or "close"
    attempt: int | None
    why: str            # open: the state that opened it; close: the reason, for the log and the bag


@dataclass
class RecordingPlan:
    """The open/close decisions, fed with (state, attempt, now) and asked what is due.
    Time is any monotonic clock in seconds; the node uses time.monotonic()."""
    post_roll_s: float = 1.0
    settle_s: float = SETTLE_S
    recording: int | None = None          # attempt whose bag is open
    is_recording: bool = False
    ended: bool = False                   # the open attempt has ended: closing after the post-roll
    close_at: float | None = None
    close_why: str = ""
    pending: tuple | None = None          # (attempt, state, open_at): an open waiting SETTLE_S
    _queue: list = field(default_factory=list)

    def on_status(self, state: str, attempt: int | None, now: float) -> None:
        if state in ACTIVE_STATES:
            if self.is_recording and self.recording == attempt and not self.ended:
                return                                    # the attempt goes on
            if self.is_recording:
                why = (f"attempt {attempt} {state} again" if self.recording == attempt
                       else f"attempt {attempt} {state}")
                self._close_now(why)
            if self.pending is None or self.pending[0] != attempt:
                self.pending = (attempt, state, now + self.settle_s)
            return
        # an end state, idle, or a state this plan does not know: no attempt is going on
        if self.pending is not None and (self.pending[0] == attempt or state not in END_STATES):
            self.pending = None
        if self.is_recording and not self.ended:
            self.ended = True
            self.close_at = now + self.post_roll_s
            if state in END_STATES and attempt == self.recording:
                self.close_why = f"post-roll after {state}"
            elif state in END_STATES:
                self.close_why = f"post-roll after attempt {attempt} {state} (another attempt)"
            else:
                self.close_why = f"post-roll after state {state!r} (the attempt ended without an end state)"

    def _close_now(self, why: str) -> None:
        self._queue.append(Action("close", self.recording, why))
        self.is_recording = False
        self.recording = None
        self.ended = False
        self.close_at = None

    def due(self, now: float) -> list[Action]:
        """Actions to carry out now, in order; an "open" marks the attempt as recorded."""
        if self.is_recording and self.close_at is not None and now >= self.close_at:
            self._close_now(self.close_why)
        if self.pending is not None and now >= self.pending[2]:
            attempt, state, _ = self.pending
            self.pending = None
            if self.is_recording:       # cannot happen (an open closes first); kept safe
                self._close_now(f"attempt {attempt} {state}")
            self._queue.append(Action("open", attempt, state))
            self.is_recording, self.recording, self.ended, self.close_at = True, attempt, False, None
        out, self._queue = self._queue, []
        return out

    def shutdown(self) -> list[Action]:
        """The node stops: close what is open now (a bag is never left unreadable)."""
        self.pending = None
        if self.is_recording:
            self._close_now("shutdown")
        out, self._queue = self._queue, []
        return out
