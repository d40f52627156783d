"""Recover an attempt's rosbag2 MCAP that was never closed (the recorder killed with SIGKILL, the
computer lost power): the file then lacks its summary, footer and closing magic, and its folder
lacks metadata.yaml, so no reader opens it. What the recorder flushed (every chunk it closed: it
closes one every `flush_period_s`, docs/recording.md) is read record by record from the
specification (mcap.dev/spec: Header, then Schema, Channel and Chunk records; a Chunk holds
Schema, Channel and Message records) up to the first truncated record, and written again as a
complete rosbag2 folder beside the original, which is left as it is. The file is read without ROS;
each type's definition and hash come from the recorder's own MessageTypes (the installed
interfaces), as when it was recorded, else from the definition the bag itself carries (the MCAP
schema record, the sqlite3 `message_definitions` table): a type this computer does not know is
kept. A topic that still cannot be written is named with the reason (`Scan.dropped`).

Whether a bag needs recovering is decided from its storage file, not from its metadata.yaml: an
MCAP file without its closing magic (the recorder killed, or a copy of a closed bag interrupted,
which leaves its metadata.yaml beside a cut file) is recovered; one with it was closed.

A sqlite3 bag (`storage: sqlite3`) killed the same way has its rows up to the recorder's last
commit (every `flush_period_s`) in its `.db3`, but no metadata.yaml: its `topics` and `messages`
tables (rosbag2's schema, version 4) are read from a consistent copy of the file (after a killed
writer, a copy on which SQLite rolls the hot journal back; never the original) and written again
as a complete sqlite3 bag. A file another process still writes is refused.

Usage: `lhd bag recover BAG [--out DIR]` (default DIR: BAG_recovered).
"""
from __future__ import annotations

import shutil
import sqlite3
import struct
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_DATA_END = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F


class RecoverError(ValueError):
    """A file that is not a recoverable MCAP: what is wrong and what is expected."""


@dataclass
class Scan:
    """What an unclosed MCAP holds: schemas {id: (name, encoding, text)}, channels {id: (schema id,
    topic, message encoding, metadata bytes)}, messages [(channel id, log time ns, data)], and where
    the readable part ends (None: the file is complete up to its data end)."""
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    messages: list = field(default_factory=list)
    truncated_at: int | None = None
    chunks: int = 0
    storage: str = "mcap"            # or sqlite3 (scan_sqlite3: the committed rows; no chunks)
    written: dict = field(default_factory=dict)      # recover: topic -> messages written
    dropped: dict = field(default_factory=dict)      # recover: topic -> why its messages were not written


class _Buf:
    def __init__(self, data: bytes | memoryview):
        self.d, self.p = memoryview(data), 0

    def u(self, fmt: str):
        size = struct.calcsize("<" + fmt)
        if self.p + size > len(self.d):
            raise RecoverError("record shorter than its fields")
        v = struct.unpack_from("<" + fmt, self.d, self.p)[0]
        self.p += size
        return v

    def raw(self, n: int) -> bytes:
        if self.p + n > len(self.d):
            raise RecoverError("record shorter than its fields")
        v = bytes(self.d[self.p:self.p + n])
        self.p += n
        return v

    def string(self) -> str:
        return self.raw(self.u("I")).decode()

    def left(self) -> int:
        return len(self.d) - self.p


def _records(data: memoryview, start: int):
    """(op, body, offset) of each complete record from `start`; stops at a truncated one, and
    returns (via StopIteration's value) the offset where reading stopped, or None at a data end."""
    p = start
    while p < len(data):
        if p + 9 > len(data):
            return p
        op = data[p]
        length = struct.unpack_from("<Q", data, p + 1)[0]
        if p + 9 + length > len(data):
            return p
        yield op, data[p + 9:p + 9 + length], p
        if op in (OP_DATA_END, OP_FOOTER):
            return None
        p += 9 + length
    return None


def _take(scan: Scan, op: int, body: memoryview) -> None:
    b = _Buf(body)
    if op == OP_SCHEMA:
        sid = b.u("H")
        scan.schemas[sid] = (b.string(), b.string(), b.raw(b.u("I")).decode())
    elif op == OP_CHANNEL:
        cid, sid, topic, enc = b.u("H"), b.u("H"), b.string(), b.string()
        scan.channels[cid] = (sid, topic, enc, b.raw(b.u("I")))
    elif op == OP_MESSAGE:
        cid, _seq, log_time, _pub_time = b.u("H"), b.u("I"), b.u("Q"), b.u("Q")
        scan.messages.append((cid, log_time, b.raw(b.left())))


def scan_mcap(path) -> Scan:
    """Every schema, channel and message of the complete records of an MCAP file."""
    data = memoryview(Path(path).read_bytes())
    if bytes(data[:8]) != MAGIC:
        raise RecoverError(f"{path}: not an MCAP file (no MCAP magic at the start)")
    scan = Scan()
    gen = _records(data, 8)
    while True:
        try:
            op, body, _ = next(gen)
        except StopIteration as stop:
            scan.truncated_at = stop.value
            break
        if op == OP_CHUNK:
            b = _Buf(body)
            b.u("Q"), b.u("Q")
            size, _crc, compression = b.u("Q"), b.u("I"), b.string()
            records = b.raw(b.u("Q"))
            if compression:
                raise RecoverError(f"{path}: chunk compression {compression!r}; the recorder writes "
                                   "uncompressed chunks, which is what this recovers")
            if len(records) != size:
                raise RecoverError(f"{path}: a chunk of {len(records)} bytes says {size}")
            inner = _records(memoryview(records), 0)
            for iop, ibody, _ in inner:
                _take(scan, iop, ibody)
            scan.chunks += 1
        else:
            _take(scan, op, body)
    return scan


SQLITE_RESERVED_BYTE = 0x40000001     # SQLite's unix VFS: PENDING_BYTE (1 GiB) + 1, the writer's lock


def sqlite_writer_alive(path: Path) -> bool:
    """True when another process holds the SQLite RESERVED lock on `path`: a writer in a
    transaction (rosbags' writer keeps one open between its commits), so the file is still being
    written. Tried with a non-blocking POSIX lock on that byte, released at once."""
    import fcntl

    try:
        with path.open("rb+") as f:
            try:
                fcntl.lockf(f, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, SQLITE_RESERVED_BYTE)
            except OSError:
                return True
            fcntl.lockf(f, fcntl.LOCK_UN, 1, SQLITE_RESERVED_BYTE)
    except OSError:
        return False          # cannot open it for the test (read-only media): nobody writes there
    return False


def _snapshot(path: Path, copy: Path) -> None:
    """A consistent copy of the SQLite file `path` at `copy`, the original untouched. A file a
    writer still holds is refused: a copy taken mid-write had a hole of 94 messages or was
    'malformed', and a read lock held for the copy made the writer's commit fail (a review). A
    writer that was killed leaves a hot journal, which a read-only connection may not roll back:
    the files are copied and SQLite rolls the journal back on the copy. Without a journal (or in
    WAL mode) SQLite's backup API on a read-only connection copies one commit's state."""
    if sqlite_writer_alive(path):
        raise RecoverError(f"{path} is still being written (another process holds its write lock): stop the "
                           "recorder first; a running recorder closes the bag itself at the attempt's end")
    if Path(str(path) + "-journal").is_file():
        try:
            shutil.copyfile(path, copy)
            shutil.copyfile(str(path) + "-journal", str(copy) + "-journal")
        except OSError as exc:
            raise RecoverError(f"cannot copy {path} and its journal to {copy.parent} to read them ({exc}); expected "
                               "room there for a copy of the bag") from None
        return
    src = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True, timeout=10.0)
    try:
        dst = sqlite3.connect(copy)
        try:
            src.backup(dst)
        finally:
            dst.close()
    except sqlite3.Error as exc:
        raise RecoverError(f"{path}: SQLite cannot copy it ({exc})") from None
    finally:
        src.close()


def scan_sqlite3(path, work_dir=None) -> Scan:
    """What a never-closed rosbag2 sqlite3 file holds, in the Scan's terms: a schema and a channel
    per row of `topics` (channel metadata: the parsed offered QoS profiles), the committed
    `messages`, read from a consistent copy (_snapshot), so the original stays as it is. The copy
    lies in a temporary folder under `work_dir` (recover: the output's folder, which must hold a
    bag of about that size anyway; the system's temporary folder is often a small RAM disk),
    removed when read."""
    from rosbags.rosbag2.metadata import parse_qos

    path = Path(path)
    with path.open("rb") as f:
        if f.read(16) != b"SQLite format 3\x00":
            raise RecoverError(f"{path}: not an SQLite database (no 'SQLite format 3' header)")
    with tempfile.TemporaryDirectory(dir=work_dir, prefix=".lhd_recover_") as tmp:
        copy = Path(tmp) / path.name
        _snapshot(path, copy)
        conn = sqlite3.connect(copy)
        try:
            cols = {r[1] for r in conn.execute("PRAGMA table_info(topics)")}
            if not {"id", "name", "type", "serialization_format"} <= cols:
                raise RecoverError(f"{path}: no rosbag2 `topics` table (expected a rosbag2 sqlite3 bag)")
            qos_col = "offered_qos_profiles" if "offered_qos_profiles" in cols else "''"
            scan = Scan(storage="sqlite3")
            # the definitions the bag carries (rosbag2 schema 4), for a type this computer does not know
            defs = {}
            if conn.execute("SELECT 1 FROM sqlite_master WHERE type='table' AND name='message_definitions'"
                            ).fetchone():
                defs = {t: (enc, text) for t, enc, text in conn.execute(
                    "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions")}
            for tid, name, typ, fmt, qos in conn.execute(
                    f"SELECT id, name, type, serialization_format, {qos_col} FROM topics ORDER BY id"):
                enc, text = defs.get(typ, ("ros2msg", ""))
                scan.schemas[tid] = (typ, enc, text)
                try:
                    profiles = parse_qos(qos) if qos else []
                except Exception:  # noqa: BLE001 - a QoS text this rosbags cannot read: the reader's defaults
                    profiles = []
                scan.channels[tid] = (tid, name, fmt, profiles)
            scan.messages = [(tid, int(t), bytes(d)) for tid, t, d in
                             conn.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id")]
        except sqlite3.DatabaseError as exc:
            raise RecoverError(f"{path}: SQLite cannot read it ({exc})") from None
        finally:
            conn.close()
    return scan


def _bag_definition(name: str, encoding: str, text: str) -> tuple[str, str]:
    """(msgdef, rihs01) of `name` from the definition the bag carries (ros2msg text with its dependencies,
    as rosbag2 writes it), registered in a typestore of its own; ValueError when there is none."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if encoding != "ros2msg" or not text.strip():
        raise ValueError(f"the bag carries no ros2msg definition of it (encoding {encoding!r})")
    try:
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(text, name))
        return store.generate_msgdef(name, ros_version=2)[0], store.hash_rihs01(name)
    except Exception as exc:  # noqa: BLE001 - rosbags' parser and typestore errors: the reason, said
        raise ValueError(f"its definition in the bag does not parse ({exc})") from None


def _closed(file: Path) -> bool:
    """True when the storage file was closed: an MCAP file that ends with its magic (footer and closing
    magic are written last); a .db3 without a hot journal that SQLite finds intact."""
    if file.suffix == ".mcap":
        size = file.stat().st_size
        with file.open("rb") as f:
            if size < 2 * len(MAGIC):
                return False
            f.seek(size - len(MAGIC))
            return f.read(len(MAGIC)) == MAGIC
    if Path(str(file) + "-journal").is_file():
        return False
    try:
        conn = sqlite3.connect(f"{file.resolve().as_uri()}?mode=ro", uri=True)
        try:
            return conn.execute("PRAGMA quick_check").fetchone()[0] == "ok"
        finally:
            conn.close()
    except sqlite3.Error:
        return False


def recover(bag, out=None) -> tuple[Path, Scan]:
    """Write the readable part of the never-closed (or cut) bag folder `bag` as a complete rosbag2 folder
    (version 9, the original's storage: MCAP or sqlite3) at `out` (default: BAG_recovered); the
    original is not touched. Returns (out, scan), scan.written the messages written per topic and
    scan.dropped the topics left out with the reason. RecoverError saying why not."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.storage_mcap import get_qos

    from lhd_loading_ros.nodes.recorder_node import MessageTypes

    bag = Path(bag)
    if not bag.is_dir():
        raise RecoverError(f"{bag}: not a folder (expected an attempt's bag folder, e.g. runs/real/.../bags/attempt_0001)")
    files = sorted(bag.glob("*.mcap")) + sorted(bag.glob("*.db3"))
    if len(files) != 1:
        raise RecoverError(f"{bag}: expected one .mcap or .db3 file, found {len(files)}")
    if files[0].stat().st_size == 0:
        raise RecoverError(f"{files[0]} is empty: nothing was flushed before the recorder stopped")
    # decided from the file (a review, 2026-11-30: an interrupted copy keeps metadata.yaml beside a cut file)
    if (bag / "metadata.yaml").is_file() and _closed(files[0]):
        raise RecoverError(f"{bag} was closed (its {files[0].name} is complete): it needs no recovery "
                           f"(`lhd replay {bag}`)")
    out = Path(out) if out is not None else bag.with_name(bag.name + "_recovered")
    if out.exists():
        raise RecoverError(f"{out} exists: give another --out (nothing is overwritten)")
    if not out.parent.is_dir():
        raise RecoverError(f"{out.parent}: no such folder for --out (expected an existing folder to write the "
                           "recovered bag in)")
    sqlite = files[0].suffix == ".db3"
    scan = scan_sqlite3(files[0], work_dir=out.parent) if sqlite else scan_mcap(files[0])
    if not scan.messages:
        raise RecoverError(f"{files[0]}: no complete message in it (nothing was flushed before the recorder stopped)")
    writer = Writer(out, version=9, storage_plugin=StoragePlugin.SQLITE3 if sqlite else StoragePlugin.MCAP)
    writer.open()
    try:
        for k, v in _custom_data(bag).items():       # a cut copy's metadata.yaml: the attempt, prefix, ...
            writer.set_custom_data(k, v)
        writer.set_custom_data("lhd.recovered_from", str(files[0]))
        conns, types = {}, MessageTypes()
        for cid, (sid, topic, enc, meta) in sorted(scan.channels.items()):
            name, encoding, text = scan.schemas.get(sid, ("", "", ""))
            if not name:
                scan.dropped[topic] = "its schema was not flushed before the recorder stopped"
                continue
            try:
                msgdef, rihs = types.definition(name)
            except ValueError as exc:
                # a type this computer does not know (a review, 2026-11-30: such topics were dropped without a
                # word): the definition the bag carries
                try:
                    msgdef, rihs = _bag_definition(name, encoding, text)
                except ValueError as exc2:
                    scan.dropped[topic] = f"type {name}: {exc}; {exc2}"
                    continue
            conns[cid] = writer.add_connection(topic, name, msgdef=msgdef, rihs01=rihs, serialization_format=enc,
                                               offered_qos_profiles=meta if sqlite else get_qos(meta))
        for cid, t, data in sorted(scan.messages, key=lambda m: m[1]):
            if cid in conns:
                writer.write(conns[cid], t, data)
                topic = scan.channels[cid][1]
                scan.written[topic] = scan.written.get(topic, 0) + 1
            elif cid not in scan.channels:
                scan.dropped.setdefault(f"(channel {cid})", "its channel record was not flushed")
    finally:
        writer.close()
    return out, scan


def _custom_data(bag: Path) -> dict:
    """The custom_data of the bag's metadata.yaml, if it has a readable one ({} otherwise)."""
    import yaml

    try:
        info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        return {str(k): str(v) for k, v in (info.get("custom_data") or {}).items()}
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return {}
