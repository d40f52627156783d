"""An MCAP file's structure read by hand from the specification (mcap.dev/spec), to check the
recorder's bags without the library that wrote them: the magic at both ends, the header's
profile, and the summary section's schemas, channels and statistics."""
from __future__ import annotations

import struct
from pathlib import Path

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_STATISTICS = 0x01, 0x02, 0x03, 0x04, 0x0B


class _Buf:
    def __init__(self, data: bytes, pos: int = 0):
        self.d, self.p = data, pos

    def u(self, fmt: str):
        v = struct.unpack_from("<" + fmt, self.d, self.p)[0]
        self.p += struct.calcsize("<" + fmt)
        return v

    def raw(self, n: int) -> bytes:
        v = self.d[self.p:self.p + n]
        self.p += n
        return v

    def string(self) -> str:
        return self.raw(self.u("I")).decode()


def read_summary(path: Path) -> dict:
    data = Path(path).read_bytes()
    assert data[:8] == MAGIC, f"{path}: no MCAP magic at the start"
    assert data[-8:] == MAGIC, f"{path}: no MCAP magic at the end (file not closed)"
    head = _Buf(data, 8)
    assert head.u("B") == OP_HEADER
    head.u("Q")
    profile, library = head.string(), head.string()
    foot = _Buf(data, len(data) - 8 - 29)
    assert foot.u("B") == OP_FOOTER and foot.u("Q") == 20
    summary_start, summary_offset_start = foot.u("Q"), foot.u("Q")
    assert summary_start > 0, "no summary section"
    end = summary_offset_start or len(data) - 8 - 29
    b = _Buf(data, summary_start)
    schemas, channels, stats = {}, {}, None
    while b.p < end:
        op, length = b.u("B"), b.u("Q")
        rec = _Buf(b.raw(length))
        if op == OP_SCHEMA:
            sid = rec.u("H")
            schemas[sid] = {"name": rec.string(), "encoding": rec.string(), "data": rec.raw(rec.u("I")).decode()}
        elif op == OP_CHANNEL:
            cid, sid, topic, enc = rec.u("H"), rec.u("H"), rec.string(), rec.string()
            size = rec.u("I")
            meta, stop = {}, rec.p + size
            while rec.p < stop:
                k = rec.string()
                meta[k] = rec.string()
            channels[cid] = {"schema_id": sid, "topic": topic, "encoding": enc, "metadata": meta}
        elif op == OP_STATISTICS:
            count = rec.u("Q")
            rec.u("H"), rec.u("I"), rec.u("I"), rec.u("I"), rec.u("I"), rec.u("Q"), rec.u("Q")
            size = rec.u("I")
            per, stop = {}, rec.p + size
            while rec.p < stop:
                cid = rec.u("H")
                per[cid] = rec.u("Q")
            stats = {"message_count": count, "per_channel": per}
    return {"profile": profile, "library": library, "schemas": schemas, "channels": channels, "statistics": stats}
