"""Serial protocol between the host and the LHD's Arduino Due (docs/serial_protocol.md, the
single truth of the wire format; this module follows it).

Wire format: every frame is a packet, COBS-encoded, followed by one 0x00 delimiter.
Packet = version (u8) | type (u8) | seq (u8) | length (u8) | payload (length bytes) | crc16 (u16 LE),
with CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor) over
version..payload. All multi-byte fields little-endian (the Due's native order). Sequence
numbers: one counter per sender and frame type (TxSequence); a receiver checks them per type
(FrameParser), so a gap says which kind of frame was lost.

Frame types: 0x01 sensor (device -> host), 0x02 command and 0x03 heartbeat (host -> device), and
the optional 0x04 load cell (device -> host, 10 Hz, only from a device with the bucket's HX711
amplifier). 0x04 came after the first devices, in version 1: a host that does not take it drops
and counts it (unknown_types) and, sequence numbers being per type, sees no gap in the others.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

VERSION = 1
TYPE_SENSOR = 0x01
TYPE_COMMAND = 0x02
TYPE_HEARTBEAT = 0x03
TYPE_LOAD_CELL = 0x04
MAX_PAYLOAD = 64
HEADER = struct.Struct("<BBBB")
CRC = struct.Struct("<H")
MAX_PACKET = HEADER.size + MAX_PAYLOAD + CRC.size   # 70 bytes
# the largest COBS-encoded packet, without its 0x00 delimiter (COBS adds one byte per 254
# started): 71 bytes, the most a receiver keeps of a partial frame
MAX_ENCODED = MAX_PACKET + 1 + MAX_PACKET // 255
TYPE_NAMES = {TYPE_SENSOR: "sensor", TYPE_COMMAND: "command", TYPE_HEARTBEAT: "heartbeat",
              TYPE_LOAD_CELL: "load cell"}
ALL_TYPES = frozenset(TYPE_NAMES)

# scales: physical value = raw * scale
ANGLE_SCALE = 1e-4      # rad per count (int16: +-3.2767 rad)
RATE_SCALE = 1e-4       # rad/s per count (int16: +-3.2767 rad/s)
WHEEL_SCALE = 1e-3      # rad/s per count (int16: +-32.767 rad/s)
CURRENT_SCALE = 1e-3    # A per count (uint16: 0..65.535 A)
MASS_SCALE = 1e-3       # kg per count (int32, grams)

FLAG_ENABLED = 0x01
FLAG_WATCHDOG = 0x02
FLAG_ESTOP = 0x04
# held: the device keeps the machine stopped until a stop frame (enable = 0): after power-up and any
# reset, while the e-stop is pressed and after its release, during and after a sensor fault
FLAG_HELD = 0x08
FLAG_SENSOR_FAULT = 0x10  # a reading is not one: an arm angle NaN or beyond its joint's limits by 0.3 rad; any NaN
FLAG_RESET = 0x20         # the device was reset (power-up, brown-out, its watchdog) and has had no stop frame since

# load-cell frame: the HX711's conversions are 24-bit two's complement, sent sign-extended
RAW_MIN, RAW_MAX = -(1 << 23), (1 << 23) - 1
LC_CALIBRATED = 0x01    # the firmware has a scale (counts per kg): without it the mass field is 0
LC_TARED = 0x02         # the zero (offset) is known: compiled, or taken at power-up
LC_SATURATED = 0x04     # the conversion is at the amplifier's limit (input beyond its full scale)
LC_STALE = 0x08         # no conversion from the amplifier recently (unplugged, unpowered, hung)


def crc16_ccitt(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE. check('123456789') == 0x29B1."""
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


# table-driven version (the parser's hot path)
_CRC_TABLE = []
for _i in range(256):
    _c = _i << 8
    for _ in range(8):
        _c = ((_c << 1) ^ 0x1021) & 0xFFFF if _c & 0x8000 else (_c << 1) & 0xFFFF
    _CRC_TABLE.append(_c)


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    t = _CRC_TABLE
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ t[(crc >> 8) ^ b]
    return crc


def cobs_encode(data: bytes) -> bytes:
    """Consistent Overhead Byte Stuffing (Cheshire & Baker): the output holds no 0x00."""
    out = bytearray(b"\x00")
    code_idx = 0
    code = 1
    for byte in data:
        if byte == 0:
            out[code_idx] = code
            code_idx = len(out)
            out.append(0)
            code = 1
        else:
            out.append(byte)
            code += 1
            if code == 0xFF:
                out[code_idx] = code
                code_idx = len(out)
                out.append(0)
                code = 1
    out[code_idx] = code
    return bytes(out)


class CobsError(ValueError):
    pass


def cobs_decode(data: bytes) -> bytes:
    out = bytearray()
    idx = 0
    n = len(data)
    while idx < n:
        code = data[idx]
        if code == 0:
            raise CobsError("zero byte inside a COBS frame")
        end = idx + code
        if end > n:
            raise CobsError("COBS code runs past the end of the frame")
        block = data[idx + 1:end]
        if 0 in block:
            raise CobsError("zero byte inside a COBS frame")
        out += block
        idx = end
        if code != 0xFF and idx < n:
            out.append(0)
    return bytes(out)


# ---------------------------------------------------------------- payloads
@dataclass(frozen=True)
class SensorFrame:
    """Device -> host, >= 50 Hz."""
    device_time_us: int
    boom_angle: float      # rad, 0 = attack pose, negative = lifted
    bucket_angle: float    # rad, 0 = attack pose, positive = curled back
    boom_rate: float       # rad/s
    bucket_rate: float     # rad/s
    wheel_fl: float        # rad/s
    wheel_fr: float        # rad/s
    wheel_rear: float      # rad/s (rear axle: one motor through a differential)
    current_fl: float      # A
    current_fr: float      # A
    current_rear: float    # A
    valve_boom: int        # -1 lower, 0 hold, +1 raise (what the valve is doing)
    valve_bucket: int      # -1 tilt forward, 0 hold, +1 curl back
    flags: int = 0

    STRUCT = struct.Struct("<IhhhhhhhHHHbbB")


@dataclass(frozen=True)
class CommandFrame:
    """Host -> device."""
    wheel_setpoint: float  # rad/s, >= 0
    valve_boom: int        # -1, 0, +1
    valve_bucket: int      # -1, 0, +1
    enable: bool

    STRUCT = struct.Struct("<hbbB")

    @classmethod
    def stop(cls) -> "CommandFrame":
        return cls(0.0, 0, 0, False)

    @property
    def is_stop(self) -> bool:
        return self.wheel_setpoint == 0.0 and self.valve_boom == 0 and self.valve_bucket == 0 and not self.enable


@dataclass(frozen=True)
class HeartbeatFrame:
    """Host -> device, 1 Hz: keeps the link alive and carries the host clock."""
    host_time_ms: int

    STRUCT = struct.Struct("<I")


@dataclass(frozen=True)
class LoadCellFrame:
    """Device -> host, 10 Hz, optional: the bucket's load cell (docs/serial_protocol.md)."""
    device_time_us: int    # device clock when the reported conversion was read from the amplifier
    mass: float            # kg, (raw - offset) / scale, tared (signed: tare drift); 0 unless calibrated and tared
    raw: int               # HX711 counts, 24-bit two's complement sign-extended
    flags: int = 0         # LC_CALIBRATED | LC_TARED | LC_SATURATED | LC_STALE

    STRUCT = struct.Struct("<IiiB")

    @property
    def calibrated(self) -> bool:
        return bool(self.flags & LC_CALIBRATED)

    @property
    def tared(self) -> bool:
        return bool(self.flags & LC_TARED)

    @property
    def saturated(self) -> bool:
        return bool(self.flags & LC_SATURATED)

    @property
    def stale(self) -> bool:
        return bool(self.flags & LC_STALE)


class ProtocolError(ValueError):
    """A packet that must be dropped; the message names the fault."""


class CrcError(ProtocolError):
    pass


class UnknownTypeError(ProtocolError):
    """A well-formed packet (good CRC, version 1) of a type the receiver does not take."""


def _i16(v: float, scale: float, name: str) -> int:
    raw = int(round(v / scale))
    if not -32768 <= raw <= 32767:
        raise ProtocolError(f"{name} = {v} out of range (int16 at scale {scale})")
    return raw


def _u16(v: float, scale: float, name: str) -> int:
    raw = int(round(v / scale))
    if not 0 <= raw <= 65535:
        raise ProtocolError(f"{name} = {v} out of range (uint16 at scale {scale})")
    return raw


def _i32(v: float, scale: float, name: str) -> int:
    raw = int(round(v / scale))
    if not -(1 << 31) <= raw < (1 << 31):
        raise ProtocolError(f"{name} = {v} out of range (int32 at scale {scale})")
    return raw


def _raw24(v: int) -> int:
    if not RAW_MIN <= v <= RAW_MAX:
        raise ProtocolError(f"raw = {v} out of range: an HX711 conversion is 24-bit, {RAW_MIN} .. {RAW_MAX}")
    return v


def _tri(v: int, name: str) -> int:
    if v not in (-1, 0, 1):
        raise ProtocolError(f"{name} = {v} must be -1, 0 or +1")
    return v


def pack_payload(msg) -> tuple[int, bytes]:
    if isinstance(msg, SensorFrame):
        return TYPE_SENSOR, SensorFrame.STRUCT.pack(
            msg.device_time_us & 0xFFFFFFFF,
            _i16(msg.boom_angle, ANGLE_SCALE, "boom_angle"), _i16(msg.bucket_angle, ANGLE_SCALE, "bucket_angle"),
            _i16(msg.boom_rate, RATE_SCALE, "boom_rate"), _i16(msg.bucket_rate, RATE_SCALE, "bucket_rate"),
            _i16(msg.wheel_fl, WHEEL_SCALE, "wheel_fl"), _i16(msg.wheel_fr, WHEEL_SCALE, "wheel_fr"),
            _i16(msg.wheel_rear, WHEEL_SCALE, "wheel_rear"),
            _u16(msg.current_fl, CURRENT_SCALE, "current_fl"), _u16(msg.current_fr, CURRENT_SCALE, "current_fr"),
            _u16(msg.current_rear, CURRENT_SCALE, "current_rear"),
            _tri(msg.valve_boom, "valve_boom"), _tri(msg.valve_bucket, "valve_bucket"), msg.flags & 0xFF)
    if isinstance(msg, CommandFrame):
        return TYPE_COMMAND, CommandFrame.STRUCT.pack(
            _i16(msg.wheel_setpoint, WHEEL_SCALE, "wheel_setpoint"), _tri(msg.valve_boom, "valve_boom"),
            _tri(msg.valve_bucket, "valve_bucket"), 1 if msg.enable else 0)
    if isinstance(msg, HeartbeatFrame):
        return TYPE_HEARTBEAT, HeartbeatFrame.STRUCT.pack(msg.host_time_ms & 0xFFFFFFFF)
    if isinstance(msg, LoadCellFrame):
        return TYPE_LOAD_CELL, LoadCellFrame.STRUCT.pack(msg.device_time_us & 0xFFFFFFFF,
                                                         _i32(msg.mass, MASS_SCALE, "mass"), _raw24(msg.raw),
                                                         msg.flags & 0xFF)
    raise ProtocolError(f"cannot encode {type(msg).__name__}")


def frame_bytes(ftype: int, seq: int, payload: bytes) -> bytes:
    """COBS(header | payload | crc16) + 0x00 for any type (the emulator uses it to send
    frames of an unknown type)."""
    body = HEADER.pack(VERSION, ftype, seq & 0xFF, len(payload)) + payload
    return cobs_encode(body + CRC.pack(crc16(body))) + b"\x00"


def encode(msg, seq: int) -> bytes:
    """The bytes on the wire for msg with sequence number seq: COBS(packet) + 0x00."""
    ftype, payload = pack_payload(msg)
    return frame_bytes(ftype, seq, payload)


class TxSequence:
    """A sender's sequence numbers: one counter per frame type, starting at 0 and +1 (mod 256)
    per frame of that type handed to the link, never reset while the sender runs (a frame
    whose write fails still used its number: the receiver rightly sees it as lost)."""

    def __init__(self):
        self._next: dict[int, int] = {}

    def encode(self, msg) -> bytes:
        ftype, payload = pack_payload(msg)
        seq = self._next.get(ftype, 0)
        self._next[ftype] = (seq + 1) & 0xFF
        return frame_bytes(ftype, seq, payload)


def decode_packet(packet: bytes, accept=ALL_TYPES):
    """(seq, message) from a COBS-decoded packet; raises ProtocolError naming the fault
    (CrcError for a bad CRC, UnknownTypeError for a type not in `accept`)."""
    if len(packet) < HEADER.size + CRC.size:
        raise ProtocolError(f"short packet ({len(packet)} bytes)")
    body, crc = packet[:-2], CRC.unpack(packet[-2:])[0]
    if crc16(body) != crc:
        raise CrcError("bad CRC")
    version, ftype, seq, length = HEADER.unpack(body[:4])
    if version != VERSION:
        raise ProtocolError(f"unsupported protocol version {version}")
    payload = body[4:]
    if len(payload) != length:
        raise ProtocolError(f"length field {length} != payload size {len(payload)}")
    if ftype not in accept:
        what = f"{TYPE_NAMES[ftype]} frame" if ftype in TYPE_NAMES else "unknown frame type"
        raise UnknownTypeError(f"{what} 0x{ftype:02x} not taken by this receiver")
    try:
        if ftype == TYPE_SENSOR:
            f = SensorFrame.STRUCT.unpack(payload)
            msg = SensorFrame(f[0], f[1] * ANGLE_SCALE, f[2] * ANGLE_SCALE, f[3] * RATE_SCALE, f[4] * RATE_SCALE,
                              f[5] * WHEEL_SCALE, f[6] * WHEEL_SCALE, f[7] * WHEEL_SCALE, f[8] * CURRENT_SCALE,
                              f[9] * CURRENT_SCALE, f[10] * CURRENT_SCALE, f[11], f[12], f[13])
            if msg.valve_boom not in (-1, 0, 1) or msg.valve_bucket not in (-1, 0, 1):
                raise ProtocolError("valve state not in {-1, 0, +1}")
        elif ftype == TYPE_COMMAND:
            f = CommandFrame.STRUCT.unpack(payload)
            if f[1] not in (-1, 0, 1) or f[2] not in (-1, 0, 1) or f[3] not in (0, 1):
                raise ProtocolError("command field out of range")
            msg = CommandFrame(f[0] * WHEEL_SCALE, f[1], f[2], bool(f[3]))
        elif ftype == TYPE_LOAD_CELL:
            t, mass, raw, flags = LoadCellFrame.STRUCT.unpack(payload)
            if not RAW_MIN <= raw <= RAW_MAX:
                raise ProtocolError(f"load-cell raw {raw} outside the 24-bit range {RAW_MIN} .. {RAW_MAX}")
            msg = LoadCellFrame(t, mass / 1000.0, raw, flags)   # grams -> kg; 23400 g gives 23.4 exactly
        else:
            msg = HeartbeatFrame(HeartbeatFrame.STRUCT.unpack(payload)[0])
    except struct.error as exc:
        raise ProtocolError(f"payload of type 0x{ftype:02x} has the wrong size: {exc}") from None
    return seq, msg


class FrameParser:
    """Streaming parser: feed it any bytes, get whole frames back. Never raises on input;
    resynchronises on the next 0x00; keeps at most MAX_ENCODED bytes of a partial frame.

    `accept`: the frame types this receiver takes (the host: sensor and load-cell frames; the
    device: command and heartbeat frames); any other well-formed frame counts as unknown_types.
    Counters (cumulative for the parser's life, reset_link() keeps them): frames, crc_errors,
    framing_errors (COBS, size, version, length, payload size, field range), overflows,
    unknown_types, seq_gaps (frames whose seq is not the last of their type + 1) and
    frames_lost (how many numbers each gap skipped), as docs/serial_protocol.md defines them."""

    def __init__(self, accept=ALL_TYPES):
        self.accept = frozenset(accept)
        self._buf = bytearray()
        self._discarding = False
        self.frames = 0
        self.crc_errors = 0
        self.framing_errors = 0
        self.overflows = 0
        self.unknown_types = 0
        self.seq_gaps = 0
        self.frames_lost = 0
        self._last_seq: dict[type, int] = {}

    @property
    def buffered(self) -> int:
        return len(self._buf)

    def reset_link(self) -> None:
        """A (re)opened link: drop the partial frame and the sequence references (the first
        frame of each type on the new link starts afresh); the counters stay."""
        self._buf.clear()
        self._discarding = False
        self._last_seq.clear()

    def counters(self) -> dict:
        return {"frames": self.frames, "crc_errors": self.crc_errors, "framing_errors": self.framing_errors,
                "overflows": self.overflows, "unknown_types": self.unknown_types, "sequence_gaps": self.seq_gaps,
                "frames_lost": self.frames_lost}

    def feed(self, data: bytes) -> list:
        """Returns [(seq, message), ...] for the whole frames completed by data."""
        out = []
        start = 0
        while True:
            z = data.find(b"\x00", start)
            if z < 0:
                chunk = data[start:]
                if not self._discarding:
                    if len(self._buf) + len(chunk) > MAX_ENCODED:
                        self.overflows += 1
                        self._buf.clear()
                        self._discarding = True  # drop until the next delimiter
                    else:
                        self._buf += chunk
                return out
            chunk = data[start:z]
            start = z + 1
            if self._discarding:
                self._discarding = False
                self._buf.clear()
                continue
            if len(self._buf) + len(chunk) > MAX_ENCODED:
                self.overflows += 1
                self._buf.clear()
                continue
            self._buf += chunk
            frame = bytes(self._buf)
            self._buf.clear()
            if not frame:
                continue  # back-to-back delimiters: idle line
            self._decode(frame, out)

    def _decode(self, frame: bytes, out: list) -> None:
        try:
            seq, msg = decode_packet(cobs_decode(frame), self.accept)
        except CrcError:
            self.crc_errors += 1
            return
        except UnknownTypeError:
            self.unknown_types += 1
            return
        except (CobsError, ProtocolError):
            self.framing_errors += 1
            return
        key = msg.__class__
        last = self._last_seq.get(key)
        if last is not None and seq != (last + 1) & 0xFF:
            self.seq_gaps += 1
            self.frames_lost += (seq - last - 1) & 0xFF
        self._last_seq[key] = seq
        self.frames += 1
        out.append((seq, msg))
