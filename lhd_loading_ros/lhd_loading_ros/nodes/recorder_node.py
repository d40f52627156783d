"""`ros2 run lhd_loading_ros recorder_node` (node lhd_recorder): every attempt as a rosbag2.

Watches `<prefix>/episode` (the supervisor on hardware, the sim node in simulation). When an
attempt is armed (or running, if armed was missed) it opens `<run_dir>/bags/attempt_NNNN/`
(NNNN = the status's `episode` key, zero-padded to 4; an existing folder is never overwritten:
`_2`, `_3`, ... is appended and the log says so) and records every topic under the prefix plus
`extra_topics` (/joy, /diagnostics), re-discovered every `discovery_period_s` so that topics
that appear later are recorded too. It closes the bag `post_roll_s` after the attempt ended
(any end state, idle, or the next attempt armed), and on shutdown (SIGINT/SIGTERM: the run
loop's stop hook closes the writer, so a stopped recorder leaves a readable bag). The
decisions are task/recording.py's RecordingPlan; this node is the ROS and file shell.

Format: rosbag2 version 9 (ROS 2 Jazzy's), MCAP (default) or sqlite3 (`storage`), written
with the rosbags library (Ternaris, Apache-2.0): the raw CDR bytes of each message as DDS
delivered them (raw subscriptions, no deserialization), stamped with their receive time (the
node's ROS clock, as DDS received it: sim time with use_sim_time), message definitions (ros2msg) and type hashes
(RIHS01) from rosbags' Jazzy typestore, checked against the installed interfaces. Playable
with `ros2 bag play` on a full ROS install; `lhd replay BAG` prints the attempt's metrics.

QoS (lhd_loading_ros.ros.qos): `<prefix>/episode` in: STATUS_QOS, transient local, so a
recorder started late learns the current state. Recorded topics: the QoS each publisher offers,
matched as `ros2 bag record` does: reliable when every publisher is, else best effort;
transient local when every publisher is (the latched slope, toe, zones and end zone, published
long before the attempt, arrive when the bag opens), else volatile. A publisher that joins later
with a weaker QoS makes the subscription weaker (re-created), never the other way round. The
offered profiles go into the bag's metadata, so `ros2 bag play` republishes latched topics latched.

/diagnostics: recording (attempt, bag path, messages per topic) or idle (the last bag), topics
that cannot be recorded (several types published on one name, no message definition), failed writes,
messages DDS reported lost.
"""
from __future__ import annotations

import datetime
import importlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

from lhd_loading_ros.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from lhd_loading_ros.ros.params import Param, Params, steady_timer, topic_prefix
from lhd_loading_ros.ros.qos import STATUS_QOS
from lhd_loading_ros.ros.run import run_node
from lhd_loading_ros.task.recording import (RecordingPlan, attempt_number, bag_folder, next_free_attempt,
                                            topic_selected)

RECORD_DEPTH = 100      # queue of each recording subscription: a burst (a latched history, a slow
                        # disk) waits here rather than being dropped before the executor takes it
PLAN_PERIOD_S = 0.05    # how often the open/close decisions are checked (steady clock; a status acts at once)
BAG_VERSION = 9         # rosbag2 metadata version of ROS 2 Jazzy (QoS profiles as a YAML list)
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
INFINITE_NS = 0x7FFFFFFFFFFFFFFF


def default_run_dir() -> str:
    return "runs/real/" + datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%d-%H%M%S")


def _check_writable(run_dir: Path) -> None:
    """The bags folder can be created and written, or a ValueError saying so (exit 2 at start)."""
    try:
        bags = run_dir / "bags"
        bags.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=bags, prefix=".lhd_recorder_write_test_"):
            pass
    except OSError as exc:
        raise ValueError(f"parameter 'run_dir' = {str(run_dir)!r} cannot be written "
                         f"({exc.strerror or exc}); expected a folder this user can create and write "
                         f"(bags go to <run_dir>/bags/attempt_NNNN)") from None


# ---------------------------------------------------------------------- message definitions
def _share_dirs() -> list[Path]:
    dirs = [Path(p) / "share" for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return dirs + [Path(sys.prefix) / "share"]


def _interface_file(msgtype: str, suffix: str) -> Path | None:
    pkg, kind, name = msgtype.split("/")
    for d in _share_dirs():
        f = d / pkg / kind / (name + suffix)
        if f.is_file():
            return f
    return None


def _installed_hash(msgtype: str) -> str | None:
    """The RIHS01 type hash of the installed interface (share/<pkg>/msg/<Name>.json), if found."""
    f = _interface_file(msgtype, ".json")
    if f is None:
        return None
    try:
        for th in json.loads(f.read_text()).get("type_hashes", []):
            if th.get("type_name") == msgtype:
                return th.get("hash_string")
    except (OSError, ValueError):
        return None
    return None


def _referenced(fields) -> list[str]:
    out = []
    for _, (nt, arg) in fields:
        if nt == Nodetype.NAME:
            out.append(arg)
        elif nt in (Nodetype.ARRAY, Nodetype.SEQUENCE) and arg[0][0] == Nodetype.NAME:
            out.append(arg[0][1])
    return out


class MessageTypes:
    """Message definition (ros2msg text, as the MCAP schema and sqlite3 `message_definitions`
    table want it) and type hash of each recorded type: rosbags' Jazzy typestore when it agrees
    with the installed interface's hash (or no hash is installed), else the installed .msg
    files (a custom or newer interface)."""

    def __init__(self):
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self.cache: dict[str, tuple[str, str]] = {}

    def definition(self, msgtype: str) -> tuple[str, str]:
        """(msgdef, rihs01), or ValueError saying why the type cannot be described."""
        if msgtype in self.cache:
            return self.cache[msgtype]
        if msgtype.count("/") != 2:
            raise ValueError(f"type {msgtype!r}: expected package/msg/Name")
        installed = _installed_hash(msgtype)
        if msgtype in self.store.fielddefs and installed in (None, self.store.hash_rihs01(msgtype)):
            res = (self.store.generate_msgdef(msgtype, ros_version=2)[0], self.store.hash_rihs01(msgtype))
        else:
            res = self._from_installed(msgtype, installed)
        self.cache[msgtype] = res
        return res

    def _from_installed(self, msgtype: str, installed: str | None) -> tuple[str, str]:
        typs: dict = {}
        todo = [msgtype]
        while todo:
            t = todo.pop()
            if t in typs:
                continue
            f = _interface_file(t, ".msg")
            if f is None:
                raise ValueError(f"no definition of {t}: not in rosbags' Jazzy typestore and no {t}.msg under "
                                 f"{', '.join(str(d) for d in _share_dirs())}")
            parsed = get_types_from_msg(f.read_text(), t)
            typs.update(parsed)
            todo += [r for r in _referenced(parsed[t][1]) if r not in typs]
        store = get_typestore(Stores.EMPTY)
        store.register(typs)
        rihs = store.hash_rihs01(msgtype)
        if installed is not None and rihs != installed:
            raise ValueError(f"type {msgtype}: the hash of its installed .msg files ({rihs}) differs from the "
                             f"installed type description ({installed})")
        return store.generate_msgdef(msgtype, ros_version=2)[0], rihs


def message_class(msgtype: str):
    """'std_msgs/msg/Float64' -> the Python class (for the raw subscription's type support)."""
    try:
        pkg, kind, name = msgtype.split("/")
        return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
    except (ValueError, ImportError, AttributeError) as exc:
        raise ValueError(f"cannot import message type {msgtype!r}: {exc}") from None


# ---------------------------------------------------------------------- QoS
def _qos_time(duration) -> QosTime:
    ns = int(duration.nanoseconds)
    ns = min(max(ns, 0), INFINITE_NS)
    return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)


def _enum(cls, value, unknown):
    try:
        return cls(int(value))
    except ValueError:
        return unknown


def offered_qos(profile) -> Qos:
    """A discovered publisher's QoS (rclpy QoSProfile) as rosbags' Qos for the bag metadata
    (numeric policy values are rmw's, the same in both)."""
    return Qos(
        _enum(QosHistory, profile.history, QosHistory.UNKNOWN), int(profile.depth),
        _enum(QosReliability, profile.reliability, QosReliability.UNKNOWN),
        _enum(QosDurability, profile.durability, QosDurability.UNKNOWN),
        _qos_time(profile.deadline), _qos_time(profile.lifespan),
        _enum(QosLiveliness, profile.liveliness, QosLiveliness.UNKNOWN),
        _qos_time(profile.liveliness_lease_duration), bool(profile.avoid_ros_namespace_conventions))


def request_qos(profiles) -> tuple[bool, bool]:
    """(reliable, transient_local) that matches every offered profile (ros2 bag record's rule)."""
    reliable = bool(profiles) and all(p.reliability == ReliabilityPolicy.RELIABLE for p in profiles)
    latched = bool(profiles) and all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles)
    return reliable, latched


class _Recorded:
    """One recorded topic: its bag connection, subscription and counters."""

    def __init__(self, topic, msgtype, connection, reliable, latched):
        self.topic, self.msgtype, self.connection = topic, msgtype, connection
        self.reliable, self.latched = reliable, latched
        self.sub = None
        self.count = 0
        self.lost = 0


class RecorderNode(Node):
    def __init__(self, **node_kwargs):
        super().__init__("lhd_recorder", **node_kwargs)
        self.p = Params(self, [
            Param("run_dir", default_run_dir(), "run folder shared with the supervisor: bags go to "
                  "<run_dir>/bags/attempt_NNNN (default runs/real/<UTC date-time>; give both nodes the same)"),
            Param("storage", "mcap", "rosbag2 storage: mcap (the Jazzy default) or sqlite3", choices=tuple(STORAGES)),
            Param("post_roll_s", 1.0, "s recorded after an attempt ended (the stop, the machine at rest)",
                  lo=0.0, hi=60.0, on_change=self._set_post_roll),
            Param("extra_topics", ["/joy", "/diagnostics"], "absolute topics recorded besides the prefix's "
                  "([''] for none)", check=self._check_extra),
            Param("discovery_period_s", 0.5, "s between two looks for new topics while recording", lo=0.05, hi=10.0),
            Param("flush_period_s", 1.0, "s between two flushes of the open bag to disk (MCAP: the pending chunk "
                  "closed and synced; sqlite3: committed): a recorder killed or a computer that loses power leaves "
                  "all but the last period readable (`lhd bag recover BAG`); 0: only at the bag's close",
                  lo=0.0, hi=60.0),
            Param("namespace_prefix", "/lhd", "topic prefix when the node runs in the root namespace"),
        ])
        p = self.p
        self.run_dir = Path(p["run_dir"]).expanduser()
        _check_writable(self.run_dir)
        self.storage = STORAGES[p["storage"]]
        self.extra = tuple(t for t in p["extra_topics"] if t)
        self.prefix = topic_prefix(self, p["namespace_prefix"])
        self.types = MessageTypes()
        self.plan = RecordingPlan(post_roll_s=p["post_roll_s"])
        self.writer: Writer | None = None
        self._last_sim_ns = 0               # the latest log time written on the sim clock (receive_time)
        self.bag_path: Path | None = None
        self.attempt: int | None = None
        self.recorded: dict[str, _Recorded] = {}
        self.skipped: dict[str, str] = {}            # topic -> why it is not recorded
        self.failed_writes = 0
        self.failed_bags = 0
        self.bags_written = 0
        self.last_bag: str = ""
        self.last_bag_summary: str = ""
        self.status_problem: str | None = None
        self.create_subscription(DiagnosticStatus, f"{self.prefix}/episode", self._on_episode, STATUS_QOS)
        self.plan_timer = steady_timer(self, PLAN_PERIOD_S, self._tick)
        self.discovery_timer = steady_timer(self, p["discovery_period_s"], self._discover)
        self.flushes = 0
        if p["flush_period_s"] > 0:
            self.flush_timer = steady_timer(self, p["flush_period_s"], self._flush)
        self.diag = Diagnostics(self, {"recording": self._report})
        self.get_logger().info(f"recording attempts of {self.prefix}/episode into {self.run_dir}/bags "
                               f"({p['storage']}, post-roll {p['post_roll_s']:g} s)")

    @staticmethod
    def _check_extra(v) -> str | None:
        bad = [t for t in v if t and not t.startswith("/")]
        return f"topics must be absolute names starting with '/': {bad}" if bad else None

    def _set_post_roll(self, v: float) -> None:
        self.plan.post_roll_s = v

    # ------------------------------------------------------------------ attempt life cycle
    def _on_episode(self, msg: DiagnosticStatus) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        state = values.get("state", "")
        if not state:
            self.status_problem = f"{self.prefix}/episode status without a 'state' key (message {msg.message!r})"
            self.get_logger().warn(self.status_problem, throttle_duration_sec=5.0)
            return
        attempt = attempt_number(values)
        if attempt is None:
            self.status_problem = (f"{self.prefix}/episode: 'episode' = {values.get('episode')!r} is not an attempt "
                                   f"number (a whole number >= 0)")
            self.get_logger().warn(self.status_problem, throttle_duration_sec=5.0)
        else:
            self.status_problem = None
        self.plan.on_status(state, attempt, time.monotonic())
        self._tick()

    def _tick(self) -> None:
        for a in self.plan.due(time.monotonic()):
            if a.kind == "close":
                self.close_bag(a.why)
            else:
                self.open_bag(a.attempt, a.why)

    def open_bag(self, attempt: int | None, state: str) -> None:
        if attempt is None:
            attempt = next_free_attempt(self.run_dir)
            self.get_logger().warn(f"the {state} status carries no attempt number ('episode' key): "
                                   f"recording it as attempt {attempt}")
        path, note = bag_folder(self.run_dir, attempt)
        if note:
            self.get_logger().warn(note)
        try:
            # in the try: rosbags' Writer refuses in its constructor a path that exists (another recorder on the
            # run folder took the name first: a review), which from a timer callback would end the node
            writer = Writer(path, version=BAG_VERSION, storage_plugin=self.storage)
            writer.open()
        except Exception as exc:  # noqa: BLE001 - a full disk or a removed run_dir must not end the node
            self.failed_bags += 1
            self.get_logger().error(f"attempt {attempt}: cannot open the bag {path}: {exc}; this attempt is NOT recorded")
            return
        for k, v in (("lhd.attempt", str(attempt)), ("lhd.prefix", self.prefix), ("lhd.run_dir", str(self.run_dir)),
                     ("lhd.opened_on", state), ("lhd.recorder", self.get_fully_qualified_name()),
                     ("lhd.opened_utc", datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))):
            writer.set_custom_data(k, v)
        if note:
            writer.set_custom_data("lhd.note", note)
        self.writer, self.bag_path, self.attempt = writer, path, attempt
        self._last_sim_ns = 0
        self.recorded, self.skipped = {}, {}
        self.failed_writes = 0
        self.get_logger().info(f"attempt {attempt} {state}: recording into {path}")
        self._discover()

    def _flush(self) -> None:
        """What the open bag holds so far, to disk: until 2026-11-28 a recorder killed mid-attempt
        left a 0-byte MCAP (rosbags keeps the pending 1 MiB chunk in memory; a review's fault
        injection). Uses the rosbags writer's storage object (rosbags 0.11: McapWriter.close_chunk,
        .chunk, .bio; Sqlite3Writer.conn); another layout is left alone."""
        st = getattr(self.writer, "storage", None) if self.writer is not None else None
        if st is None:
            return
        try:
            if all(hasattr(st, a) for a in ("close_chunk", "chunk", "bio")):
                if st.chunk.msgs:                 # a chunk with messages (an empty one has no time range)
                    st.close_chunk()
                st.bio.flush()
                os.fsync(st.bio.fileno())
            elif hasattr(st, "conn"):
                st.conn.commit()
            else:
                return
            self.flushes += 1
        except Exception as exc:  # noqa: BLE001 - a full disk must not end the node; the close reports too
            self.get_logger().warn(f"flushing {self.bag_path}: {exc}", throttle_duration_sec=5.0)

    def close_bag(self, why: str) -> None:
        writer, self.writer = self.writer, None
        if writer is None:
            return
        for r in self.recorded.values():
            if r.sub is not None:
                self.destroy_subscription(r.sub)
                r.sub = None
        total = sum(r.count for r in self.recorded.values())
        writer.set_custom_data("lhd.closed_by", why)
        try:
            writer.close()
        except Exception as exc:  # noqa: BLE001
            self.failed_bags += 1
            self.get_logger().error(f"attempt {self.attempt}: closing the bag {self.bag_path} failed: {exc}")
            try:
                writer.abort()
            except Exception:  # noqa: BLE001
                pass
            return
        try:
            size = sum(f.stat().st_size for f in self.bag_path.iterdir() if f.is_file())
        except OSError:
            size = float("nan")
        self.bags_written += 1
        self.last_bag = str(self.bag_path)
        self.last_bag_summary = (f"{total} messages on {len(self.recorded)} topics, {size / 1024:.0f} kB, "
                                 f"closed: {why}")
        self.get_logger().info(f"attempt {self.attempt}: bag {self.bag_path} closed ({self.last_bag_summary})")

    # ------------------------------------------------------------------ topics
    def _discover(self) -> None:
        if self.writer is None:
            return
        for topic, _types in self.get_topic_names_and_types():
            if not topic_selected(topic, self.prefix, self.extra):
                continue
            pubs = self.get_publishers_info_by_topic(topic)
            if not pubs:
                continue                         # only subscribers so far: no QoS to match, nothing to record
            profiles = [i.qos_profile for i in pubs]
            reliable, latched = request_qos(profiles)
            r = self.recorded.get(topic)
            if r is not None:
                # a publisher that joined with a weaker QoS: weaken the subscription (never strengthen:
                # a new transient-local subscription would deliver the latched history twice)
                if (r.reliable and not reliable) or (r.latched and not latched):
                    self.get_logger().warn(f"{topic}: a publisher offers {'best effort' if not reliable else 'volatile'}"
                                           f" QoS: subscription re-created to match it")
                    r.reliable, r.latched = r.reliable and reliable, r.latched and latched
                    self.destroy_subscription(r.sub)
                    r.sub = self._subscribe(r)
                continue
            if topic in self.skipped:
                continue
            # the publishers' types only: a subscriber of another type (a probe, a misconfigured node)
            # receives nothing and must not keep the topic out of every bag (a review, 2026-11-28)
            pub_types = sorted({i.topic_type for i in pubs})
            if len(pub_types) != 1:
                self._skip(topic, f"several types published on one topic ({', '.join(pub_types)}): not recorded")
                continue
            msgtype = pub_types[0]
            try:
                msgdef, rihs = self.types.definition(msgtype)
                message_class(msgtype)
            except ValueError as exc:
                self._skip(topic, str(exc))
                continue
            conn = self.writer.add_connection(topic, msgtype, msgdef=msgdef, rihs01=rihs,
                                              offered_qos_profiles=[offered_qos(q) for q in profiles])
            r = _Recorded(topic, msgtype, conn, reliable, latched)
            r.sub = self._subscribe(r)
            self.recorded[topic] = r

    def receive_time(self, info: dict) -> int:
        """When DDS received the message, in ns of the node's ROS clock. DDS stamps the arrival
        on the system clock (`received_timestamp`), before the message waits for this node's
        executor: so two topics keep their true order even when the node is busy (a drift flag
        and the command after it). With use_sim_time the wait is taken off the sim clock's now, and
        the time never goes back within a bag: the sim clock jumps between callbacks and, in lockstep,
        runs faster than the wall clock the wait is measured on, so the difference went back in time
        and a bag's end status could be logged before its running statuses (a review, 2026-11-30)."""
        now = self.get_clock().now().nanoseconds
        received = int(info.get("received_timestamp", 0) or 0) if isinstance(info, dict) else 0
        if not self._sim_time_active():
            return received if received > 0 else now
        t = now if received <= 0 else max(0, now - max(0, time.time_ns() - received))
        self._last_sim_ns = max(self._last_sim_ns, t)
        return self._last_sim_ns

    def _sim_time_active(self) -> bool:
        return bool(getattr(self.get_clock(), "ros_time_is_active", False))

    def _skip(self, topic: str, why: str) -> None:
        self.skipped[topic] = why
        self.get_logger().warn(f"{topic}: {why}")

    def _subscribe(self, r: _Recorded):
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=RECORD_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE if r.reliable else ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if r.latched else DurabilityPolicy.VOLATILE)

        def on_message(data: bytes, info: dict) -> None:
            writer = self.writer
            if writer is None:
                return
            try:
                writer.write(r.connection, self.receive_time(info), data)
                r.count += 1
            except Exception as exc:  # noqa: BLE001 - count it, keep recording the other topics
                self.failed_writes += 1
                self.get_logger().error(f"{r.topic}: write to {self.bag_path} failed: {exc}",
                                        throttle_duration_sec=5.0)

        def on_lost(info) -> None:
            r.lost += int(getattr(info, "total_count_change", 1) or 1)

        try:
            events = SubscriptionEventCallbacks(message_lost=on_lost)
            return self.create_subscription(message_class(r.msgtype), r.topic, on_message, qos, raw=True,
                                            event_callbacks=events)
        except Exception:  # noqa: BLE001 - an RMW without the message-lost event: record without the count
            return self.create_subscription(message_class(r.msgtype), r.topic, on_message, qos, raw=True)

    # ------------------------------------------------------------------ diagnostics
    def _report(self):
        values = {"run_dir": str(self.run_dir), "storage": self.p["storage"], "bags_written": self.bags_written,
                  "failed_bags": self.failed_bags}
        problems = [f"{t}: {why}" for t, why in self.skipped.items()]
        if self.status_problem:
            problems.append(self.status_problem)
        if self.writer is not None:
            values.update(attempt=self.attempt, bag=str(self.bag_path), failed_writes=self.failed_writes,
                          lost=sum(r.lost for r in self.recorded.values()))
            for t, r in sorted(self.recorded.items()):
                values[f"messages {t}"] = r.count
            msg = f"recording attempt {self.attempt} into {self.bag_path}"
            if self.failed_writes:
                return ERROR, f"{msg}: {self.failed_writes} failed writes", values
            if problems:
                return WARN, f"{msg}; not recorded: {'; '.join(problems)}", values
            return OK, msg, values
        values.update(last_bag=self.last_bag, last_bag_summary=self.last_bag_summary)
        msg = "idle: waiting for an attempt to be armed" + (f" (last bag {self.last_bag})" if self.last_bag else "")
        if self.failed_bags:
            return ERROR, f"{msg}; {self.failed_bags} bag(s) could not be opened or closed (see the log)", values
        if problems:
            return WARN, f"{msg}; {'; '.join(problems)}", values
        return OK, msg, values


def main(args=None) -> int:
    return run_node(RecorderNode, "lhd_recorder", args, before_destroy=lambda node: node.close_bag("shutdown"))


if __name__ == "__main__":
    raise SystemExit(main())
