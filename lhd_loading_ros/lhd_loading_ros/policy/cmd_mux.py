"""The command mux without ROS: which of several command sources may drive the machine
(in the style of twist_mux; docs/teleop.md says where it follows twist_mux and where not).

Sources (config/cmd_mux.yaml) have a name, a topic, a priority (0..255, distinct), a timeout
and whether they are gated by the attempt state. Selection: among the sources that are fresh
(a message within their timeout, judged on arrival), not cut, and not gated unless the attempt
is running, the one of highest priority; none while the e-stop lock is engaged.

What leaves the mux:
* every accepted message of the selected source, at once (3 finite values, clamped to the
  actuator ranges; anything else rejected and counted);
* a zero AT ONCE on every transition that removes the selected source: its timeout, the
  attempt leaving `running`, the e-stop, a rejected message from it;
* zeros at idle_rate_hz while no source is selected, so the receiver actively holds the
  machine stopped;
* after an attempt ends (running -> anything else) and after the e-stop is released, every
  source is cut until it has been silent for its own timeout: the machine stays stopped until
  the next attempt, or until the operator releases and presses the deadman again.
* a running attempt whose status stops arriving (no `<prefix>/episode` for `status_timeout`,
  1.5 s: the supervisor publishes five times a second, the sim node every control period)
  ends like any other: the supervisor crashed, hung or was cut off, and nothing judges the zones,
  the timeout or the end any more. The mux's own stall does not count: a tick more than PAUSE_S
  after the previous one marks the end of a pause, and the status' age counts from then at the
  earliest (the statuses sent during the pause are not waiting in the queue: the reliable
  transport repairs them only at its next heartbeat). An attempt whose status was lost does not
  run again when its `running` status comes back (same episode key): only a new attempt runs.
Each method returns the commands to publish, in order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from lhd_loading_ros.policy.actuator_limits import ZERO, ActuatorLimits, CommandInvalid
from lhd_loading_ros.policy.status_watch import LostAttempts, StatusWatch
from lhd_loading_ros.task.attempt import STATUS_TIMEOUT_S

RUNNING = "running"
# an attempt armed, not yet running (the supervisor's arm delay): no source at all, the ungated gamepad too. The
# machine stands still in that second for every controller; before 2026-11-29 the gamepad drove through it, so a
# teleop attempt's first second of driving was neither timed nor sampled for drift (a field review)
ARMED = "armed"
STATUS_LOST = "status lost"      # episode_state after a running status stopped arriving
PAUSE_S = 0.1                    # a gap between two ticks longer than this: the mux itself did not run
ESTOP = "estop"
NONE = "none"
RESERVED = (ESTOP, NONE)
_SOURCE_KEYS = {"name", "topic", "priority", "timeout", "gated"}


class MuxConfigError(ValueError):
    """A mux configuration that cannot be used; the message names the file and the entry."""


@dataclass(frozen=True)
class Source:
    name: str
    topic: str               # relative: under the node's topic prefix; absolute: as is
    priority: int
    timeout: float
    gated: bool


@dataclass
class SourceState:
    last_arrival: float | None = None
    last_command: tuple | None = None
    cut: bool = False
    received: int = 0
    forwarded: int = 0
    rejected: int = 0
    clamped: int = 0
    dropped_cut: int = 0
    dropped_gated: int = 0
    last_rejection: str = ""


def parse_sources(doc, source: str = "") -> list[Source]:
    pre = f"{source}: " if source else ""
    if not isinstance(doc, dict) or not isinstance(doc.get("sources"), list) or not doc["sources"]:
        raise MuxConfigError(f"{pre}expected 'sources:' with a non-empty list of "
                             "{name, topic, priority, timeout, gated}")
    extra = set(doc) - {"sources"}
    if extra:
        raise MuxConfigError(f"{pre}unknown keys {sorted(extra)}; expected only 'sources'")
    out: list[Source] = []
    for i, d in enumerate(doc["sources"]):
        where = f"{pre}sources[{i}]"
        if not isinstance(d, dict) or set(d) != _SOURCE_KEYS:
            raise MuxConfigError(f"{where} = {d!r}; expected exactly the keys {sorted(_SOURCE_KEYS)}")
        name, topic, prio, timeout, gated = (d[k] for k in ("name", "topic", "priority", "timeout", "gated"))
        if not isinstance(name, str) or not name or name in RESERVED:
            raise MuxConfigError(f"{where}.name = {name!r}; expected a non-empty name other than {RESERVED}")
        if not isinstance(topic, str) or not topic.strip("/"):
            raise MuxConfigError(f"{where}.topic = {topic!r}; expected a topic name (relative to the prefix, or absolute)")
        if isinstance(prio, bool) or not isinstance(prio, int) or not 0 <= prio <= 255:
            raise MuxConfigError(f"{where}.priority = {prio!r}; expected an integer 0..255 (higher wins)")
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not math.isfinite(timeout) \
                or not 0.0 < timeout <= 10.0:
            raise MuxConfigError(f"{where}.timeout = {timeout!r}; expected seconds in (0, 10]")
        if not isinstance(gated, bool):
            raise MuxConfigError(f"{where}.gated = {gated!r}; expected true (only while an attempt runs) or false")
        out.append(Source(name, topic, prio, float(timeout), gated))
    for attr in ("name", "topic", "priority"):
        vals = [getattr(s, attr) for s in out]
        dup = sorted({v for v in vals if vals.count(v) > 1}, key=str)
        if dup:
            raise MuxConfigError(f"{pre}sources share a {attr}: {dup}; each must be distinct")
    return out


def load_sources(path) -> list[Source]:
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise MuxConfigError(f"cannot read the mux configuration {p}: {exc}") from None
    except yaml.YAMLError as exc:
        raise MuxConfigError(f"{p} is not valid YAML: {exc}") from None
    return parse_sources(doc, str(p))


@dataclass
class CommandMux:
    sources: list[Source]
    limits: ActuatorLimits
    idle_period: float = 0.1          # s between zeros while no source is selected
    episode_state: str | None = None  # None: no attempt state heard yet (gated sources are blocked)
    estop: bool = False
    selected: str | None = None
    last_output: float | None = None
    zeros_at_once: int = 0
    states: dict = field(default_factory=dict)
    status_timeout: float = STATUS_TIMEOUT_S   # s without an episode status that ends a running attempt; 0: never
    status: StatusWatch = field(default_factory=StatusWatch)   # the episode status' age (policy/status_watch.py)
    status_lost_after: float | None = None   # the silence that ended the last attempt, for explain()
    episode_key: str | None = None    # the attempt the latest status is about
    lost: LostAttempts = field(default_factory=LostAttempts)   # attempts whose status stopped arriving: none runs again

    @property
    def lost_keys(self) -> set:
        return self.lost.keys

    @property
    def lost_unkeyed(self) -> bool:
        return self.lost.unkeyed

    @property
    def resumed_at(self) -> float:
        return self.status.resumed_at

    def __post_init__(self):
        self.by_name = {s.name: s for s in self.sources}
        self.states = {s.name: SourceState() for s in self.sources}

    # ------------------------------------------------------------------ selection
    @property
    def running(self) -> bool:
        return self.episode_state == RUNNING

    @property
    def active(self) -> str:
        return ESTOP if self.estop else (self.selected or NONE)

    def _uncut(self, now: float) -> None:
        for s in self.sources:
            st = self.states[s.name]
            if st.cut and (st.last_arrival is None or now - st.last_arrival > s.timeout):
                st.cut = False

    def eligible(self, s: Source, now: float) -> bool:
        st = self.states[s.name]
        return (st.last_arrival is not None and now - st.last_arrival <= s.timeout and not st.cut
                and (not s.gated or self.running) and self.episode_state != ARMED)

    def select(self, now: float) -> str | None:
        if self.estop:
            return None
        best = None
        for s in self.sources:
            if self.eligible(s, now) and (best is None or s.priority > best.priority):
                best = s
        return best.name if best else None

    def why_not(self, s: Source, now: float) -> str:
        st = self.states[s.name]
        if self.estop:
            return "e-stop engaged"
        if st.last_arrival is None:
            return "nothing received"
        if now - st.last_arrival > s.timeout:
            return f"silent for {now - st.last_arrival:.2f} s (timeout {s.timeout:g} s)"
        if st.cut:
            return "cut until silent for its timeout (an attempt ended or the e-stop was released)"
        if self.episode_state == ARMED:
            return "held: an attempt is armed; every source waits for it to run"
        if s.gated and not self.running:
            if self.episode_state == STATUS_LOST:
                return f"gated: {self._lost_text()}"
            return f"gated: attempt state is {self.episode_state or 'unknown (no /episode publisher)'}, not running"
        if self.selected and self.selected != s.name:
            return f"overridden by {self.selected}"
        return "selected"

    def explain(self, now: float) -> str:
        if self.estop:
            return "e-stop engaged: every source blocked, zero commands"
        if self.selected:
            s = self.by_name[self.selected]
            return f"{s.name} selected (priority {s.priority})"
        lost = f"{self._lost_text()}; " if self.episode_state == STATUS_LOST else ""
        return f"no source selected, zero commands: {lost}" + "; ".join(f"{s.name}: {self.why_not(s, now)}"
                                                                         for s in self.sources)

    def _lost_text(self) -> str:
        return (f"the running attempt's status stopped arriving ({self.status_lost_after:.1f} s without one, "
                f"status_timeout {self.status_timeout:g} s): no attempt running")

    def _zero(self, now: float, out: list) -> None:
        out.append(ZERO)
        self.last_output = now
        self.zeros_at_once += 1

    def _reselect(self, now: float, out: list, taking_over: str | None = None) -> None:
        """Update the selection; a zero at once when the selected source went away, unless the
        one taking over is forwarding its command right now (`taking_over`)."""
        self._uncut(now)
        sel = self.select(now)
        if sel != self.selected:
            if self.selected is not None and (taking_over is None or sel != taking_over):
                self._zero(now, out)
            self.selected = sel

    # ------------------------------------------------------------------ inputs
    def on_command(self, name: str, data, now: float) -> list:
        out: list = []
        s, st = self.by_name[name], self.states[name]
        st.received += 1
        try:
            cmd, clamped = self.limits.check(data)
        except CommandInvalid as exc:
            st.rejected += 1
            st.last_rejection = str(exc)
            if self.selected == name:       # its last good command no longer stands
                self._zero(now, out)
            self._reselect(now, out)
            return out
        if clamped:
            st.clamped += 1
        if st.cut and (st.last_arrival is None or now - st.last_arrival > s.timeout):
            st.cut = False
        st.last_arrival, st.last_command = now, cmd
        self._reselect(now, out, taking_over=name)
        if self.selected == name:
            out.append(cmd)
            self.last_output = now
            st.forwarded += 1
        elif st.cut:
            st.dropped_cut += 1
        elif (s.gated and not self.running) or self.episode_state == ARMED:
            st.dropped_gated += 1
        return out

    def on_episode(self, state: str, now: float, key: str | None = None) -> list:
        self.status.heard(now)
        self.lost.heard(state)
        if self.lost.resumes(state, key):
            state = STATUS_LOST                   # that attempt's status was lost: it stays ended
        return self._set_episode(state, now, key)

    def _set_episode(self, state: str, now: float, key: str | None) -> list:
        out: list = []
        was_running = self.running
        self.episode_state = state
        self.episode_key = key
        if was_running and not self.running:     # the attempt ended: everything stops
            for st in self.states.values():
                st.cut = True
            if self.selected is not None:
                self._zero(now, out)
                self.selected = None
        self._reselect(now, out)
        return out

    def on_estop(self, engaged: bool, now: float) -> list:
        out: list = []
        if engaged == self.estop:
            return out
        self.estop = engaged
        if engaged:
            self.selected = None
            self._zero(now, out)                 # at once, selected source or not
        else:
            for st in self.states.values():     # nothing that kept talking through it resumes
                st.cut = True
            self._reselect(now, out)
        return out

    def tick(self, now: float) -> list:
        """Timeouts (a zero at once when the selected source goes silent, and the end of a running
        attempt whose status stopped arriving) and the idle zeros."""
        out: list = []
        age = self.status.age(now, PAUSE_S)
        if self.running and self.status_timeout > 0.0 and age is not None and age > self.status_timeout:
            self.status_lost_after = age
            self.lost.lose(self.episode_key)
            out += self._set_episode(STATUS_LOST, now, self.episode_key)
        else:
            self._reselect(now, out)
        if self.selected is None and (self.last_output is None or now - self.last_output >= self.idle_period):
            out.append(ZERO)
            self.last_output = now
        return out
