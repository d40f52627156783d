"""A second implementation of docs/serial_protocol.md, written from the document alone: it
imports nothing from lhd_hw_bridge, and reads the payload layouts (offsets, field names, types,
scales, ranges, type codes, sizes) from the document's own tables. The tests make it talk to
the bridge, the emulator and the firmware, so they check the document as much as the code."""
from __future__ import annotations

import re
import struct
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "serial_protocol.md"
INT_FORMATS = {"u8": "B", "i8": "b", "u16": "H", "i16": "h", "u32": "I", "i32": "i"}   # "Link": little-endian integers
MAX_FRAME = 71          # "Framing": an encoded frame is at most 71 bytes plus its 0x00
VERSION = 1


def crc16_ccitt_false(data: bytes) -> int:
    """Polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def cobs_encode(data: bytes) -> bytes:
    """Cheshire & Baker: each run of up to 254 non-zero bytes is preceded by its length + 1; a
    full run (code 0xFF) is not followed by an implied zero."""
    out = bytearray()
    for run in data.split(b"\x00"):
        while len(run) >= 254:
            out += b"\xff" + run[:254]
            run = run[254:]
        out += bytes([len(run) + 1]) + run
    return bytes(out)


def cobs_decode(data: bytes) -> bytes:
    out = bytearray()
    i = 0
    while i < len(data):
        code = data[i]
        if code == 0 or i + code > len(data):
            raise ValueError("bad COBS")
        out += data[i + 1:i + code]
        i += code
        if code != 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


class Layout:
    """One payload type as the document's table gives it."""

    def __init__(self, code: int, name: str, size: int, fields: list):
        self.code, self.name, self.size, self.fields = code, name, size, fields
        self.struct = struct.Struct("<" + "".join(f[1] for f in fields))
        assert self.struct.size == size, f"{name}: fields add up to {self.struct.size} bytes, heading says {size}"

    def pack(self, values: dict) -> bytes:
        raw = [int(round(values[name] / scale)) if scale != 1 else int(values[name])
               for name, _, scale, _ in self.fields]
        return self.struct.pack(*raw)

    def unpack(self, payload: bytes) -> dict:
        """Physical values; ValueError when a field is outside its listed values or its
        interval ("Receiving", step 8)."""
        raw = self.struct.unpack(payload)
        out = {}
        for (name, _, scale, allowed), r in zip(self.fields, raw):
            value = r * scale if scale != 1 else r
            if isinstance(allowed, set) and r not in allowed:
                raise ValueError(f"{name} = {r} not in {sorted(allowed)}")
            if isinstance(allowed, tuple) and not allowed[0] <= value <= allowed[1]:
                raise ValueError(f"{name} = {value} not in {allowed[0]} .. {allowed[1]}")
            out[name] = value
        return out


def read_layouts(path: Path = DOC) -> dict[int, Layout]:
    """{type code: Layout} from the sections '## <Name> frame (type 0xNN, ...), <n> bytes' (a
    name of several words becomes one with underscores: 'Load cell' -> 'load_cell'). A range
    written as listed values ('-1, 0, +1') or as an interval of integers ('-8 .. 7') is checked."""
    text = path.read_text()
    heads = list(re.finditer(r"^## ([\w ]+?) frame \(type 0x([0-9a-fA-F]{2}),[^\n]*?(\d+) bytes$", text, re.M))
    layouts = {}
    for k, h in enumerate(heads):
        body = text[h.end():heads[k + 1].start() if k + 1 < len(heads) else len(text)]
        body = body.split("\n## ")[0]
        fields, offset = [], 0
        for off, name, typ, scale, _unit, rng in re.findall(
                r"^\| (\d+) \| (\w+) \| (\w+) \| ([^|]+?) \| ([^|]+?) \| ([^|]+?) \|", body, re.M):
            fmt = INT_FORMATS[typ]
            assert int(off) == offset, f"{name} at offset {off}, the fields before it end at {offset}"
            listed = re.fullmatch(r"[-+]?\d+(?:, [-+]?\d+)+", rng.strip())
            interval = re.fullmatch(r"([-+]?\d+) \.\. ([-+]?\d+)", rng.strip())
            allowed = ({int(v) for v in rng.split(",")} if listed
                       else (int(interval.group(1)), int(interval.group(2))) if interval else None)
            fields.append((name, fmt, float(scale), allowed))
            offset += struct.calcsize("<" + fmt)
        name = h.group(1).lower().replace(" ", "_")
        layouts[int(h.group(2), 16)] = Layout(int(h.group(2), 16), name, int(h.group(3)), fields)
    return layouts


class Sender:
    """'Sequence numbers': one counter per frame type, from 0, +1 per frame, 255 -> 0."""

    def __init__(self, layouts: dict[int, Layout]):
        self.layouts = layouts
        self.next_seq: dict[int, int] = {}

    def take_seq(self, code: int) -> int:
        seq = self.next_seq.get(code, 0)
        self.next_seq[code] = (seq + 1) % 256
        return seq

    def frame(self, name: str, values: dict) -> bytes:
        lay = next(lay for lay in self.layouts.values() if lay.name == name)
        return raw_frame(lay.code, self.take_seq(lay.code), lay.pack(values))


def raw_frame(code: int, seq: int, payload: bytes, version: int = VERSION) -> bytes:
    """header | payload | crc16 (LE), COBS-encoded, then 0x00."""
    packet = bytes([version, code, seq, len(payload)]) + payload
    packet += crc16_ccitt_false(packet).to_bytes(2, "little")
    return cobs_encode(packet) + b"\x00"


class Receiver:
    """'Receiving' and 'Sequence numbers', step by step, with the document's counter names."""

    def __init__(self, layouts: dict[int, Layout], takes: set[str]):
        self.layouts = layouts
        self.takes = {c for c, lay in layouts.items() if lay.name in takes}
        self.counts = dict.fromkeys(("frames", "overflows", "framing_errors", "crc_errors", "unknown_types",
                                     "sequence_gaps", "frames_lost"), 0)
        self.reference: dict[int, int] = {}
        self.pending = bytearray()
        self.overflowing = False

    def feed(self, data: bytes) -> list[tuple[str, int, dict]]:
        out = []
        for byte in data:
            if byte != 0:
                if not self.overflowing:
                    self.pending.append(byte)
                    if len(self.pending) > MAX_FRAME:
                        self.counts["overflows"] += 1
                        self.overflowing = True
                        self.pending.clear()
                continue
            frame, skip = bytes(self.pending), self.overflowing
            self.pending.clear()
            self.overflowing = False
            if frame and not skip:
                got = self._frame(frame)
                if got:
                    out.append(got)
        return out

    def _frame(self, frame: bytes):
        c = self.counts
        try:
            packet = cobs_decode(frame)
        except ValueError:
            c["framing_errors"] += 1
            return None
        if len(packet) < 6:
            c["framing_errors"] += 1
            return None
        if crc16_ccitt_false(packet[:-2]) != int.from_bytes(packet[-2:], "little"):
            c["crc_errors"] += 1
            return None
        version, code, seq, length = packet[:4]
        if version != VERSION or length != len(packet) - 6:
            c["framing_errors"] += 1
            return None
        if code not in self.takes:
            c["unknown_types"] += 1
            return None
        lay = self.layouts[code]
        try:
            if length != lay.size:
                raise ValueError("size")
            values = lay.unpack(packet[4:-2])
        except ValueError:
            c["framing_errors"] += 1
            return None
        c["frames"] += 1
        ref = self.reference.get(code)
        if ref is not None and seq != (ref + 1) % 256:
            c["sequence_gaps"] += 1
            c["frames_lost"] += (seq - ref - 1) % 256
        self.reference[code] = seq
        return lay.name, seq, values
