"""How old the attempt's status is, in the watcher's own running time (no ROS): the rule the policy
node and the command mux share for a supervisor that crashed or hung while its last status said
`running` (docs/teleop.md rule 8).

The watcher calls `heard(now)` on every status and `age(now, late_s)` from its periodic check. A check
that comes more than `late_s` after the previous one marks the end of the watcher's OWN pause (a
stall, SIGSTOP): the age then counts from that moment at the earliest, because the statuses sent
during the pause are not waiting in its queue when it wakes (the reliable transport repairs them only
at its next heartbeat), and its pause is not the supervisor's. That late check itself judges nothing
(`age` returns None), nor does a check before any status was heard."""
from __future__ import annotations

import math


class StatusWatch:
    def __init__(self) -> None:
        self.arrival: float | None = None     # the latest status heard
        self.last_check: float | None = None
        self.resumed_at = -math.inf           # when the watcher's latest pause ended

    def heard(self, now: float) -> None:
        self.arrival = now

    def age(self, now: float, late_s: float) -> float | None:
        """Seconds since the latest status, counted from the end of the watcher's latest pause at
        the earliest; None from the first check, from a late one, and before any status."""
        on_time = self.last_check is not None and now - self.last_check <= late_s
        if self.last_check is not None and not on_time:
            self.resumed_at = now
        self.last_check = now
        if not on_time or self.arrival is None:
            return None
        return now - max(self.arrival, self.resumed_at)



class LostAttempts:
    """The attempts whose `running` status stopped arriving, which must not move the machine again when it
    comes back (a hung supervisor waking up; docs/teleop.md rule 8): every lost key, and whether an attempt
    without a key (a third-party supervisor's status) was lost, which holds until its publisher says anything
    but `running`. The policy node and the command mux share it."""

    def __init__(self) -> None:
        self.keys: set = set()
        self.unkeyed = False

    def lose(self, key: str | None) -> None:
        if key is None:
            self.unkeyed = True
        else:
            self.keys.add(key)

    def heard(self, state: str | None) -> None:
        """Every status heard: one that is not `running` means its publisher moved on."""
        if state != "running":
            self.unkeyed = False

    def resumes(self, state: str | None, key: str | None) -> bool:
        """Whether this status is a lost attempt's `running` coming back."""
        if state != "running":
            return False
        return (key in self.keys) if key is not None else self.unkeyed
