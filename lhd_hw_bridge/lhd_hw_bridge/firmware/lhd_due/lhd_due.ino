// lhd_due.ino -- reference firmware for the scaled LHD's Arduino Due (device side of
// docs/serial_protocol.md, version 1). Keep in step with that document and with
// lhd_hw_bridge/fake_due.py (the emulator the tests run against).
//
// It cannot be compiled in CI (no Arduino toolchain there). Pin numbers, encoder scaling and
// the motor/valve drivers are placeholders marked HW: to be set for the machine.

#include <Arduino.h>
#include <string.h>

// ---------------------------------------------------------------- protocol constants
static const uint8_t PROTO_VERSION = 1;
static const uint8_t TYPE_SENSOR = 0x01;
static const uint8_t TYPE_COMMAND = 0x02;
static const uint8_t TYPE_HEARTBEAT = 0x03;
static const uint8_t MAX_PAYLOAD = 64;
static const uint16_t MAX_PACKET = 4 + MAX_PAYLOAD + 2;              // 70 bytes
static const uint16_t MAX_ENCODED = MAX_PACKET + 1 + MAX_PACKET / 255; // 71: largest COBS frame, without its 0x00

static const uint32_t SENSOR_PERIOD_US = 10000;   // 100 Hz
static const uint32_t WATCHDOG_MS = 250;          // stop when command frames stop
static const float WHEEL_MAX = 2.7f;              // rad/s
static const float BOOM_MIN = -1.0f, BOOM_MAX = 0.05f;      // rad, joint limits
static const float BUCKET_MIN = -0.1f, BUCKET_MAX = 1.4f;   // rad
static const bool MAINTENANCE_BUILD = false;      // true allows lowering / forward tilt

// ---------------------------------------------------------------- state
struct Command { float wheel; int8_t boom; int8_t bucket; bool enable; };
static Command cmd = {0.0f, 0, 0, false};
static uint32_t last_cmd_ms = 0;
static bool have_cmd = false;
static bool watchdog_tripped = false;
// sequence numbers: one counter per frame type this device sends (docs/serial_protocol.md);
// it sends only sensor frames, so one counter, and only sensor frames ever use it
static uint8_t seq_sensor = 0;
static uint8_t rx_buf[MAX_ENCODED];
static uint16_t rx_len = 0;
static bool rx_discard = false;

// ---------------------------------------------------------------- CRC-16/CCITT-FALSE
static uint16_t crc16(const uint8_t *d, uint16_t n) {
  uint16_t crc = 0xFFFF;
  for (uint16_t i = 0; i < n; i++) {
    crc ^= (uint16_t)d[i] << 8;
    for (uint8_t b = 0; b < 8; b++) crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
  }
  return crc;
}

// ---------------------------------------------------------------- COBS
static uint16_t cobs_encode(const uint8_t *in, uint16_t n, uint8_t *out) {
  uint16_t code_idx = 0, o = 1;
  uint8_t code = 1;
  for (uint16_t i = 0; i < n; i++) {
    if (in[i] == 0) { out[code_idx] = code; code_idx = o++; code = 1; }
    else {
      out[o++] = in[i]; code++;
      if (code == 0xFF) { out[code_idx] = code; code_idx = o++; code = 1; }
    }
  }
  out[code_idx] = code;
  return o;
}

// returns decoded length, or -1 on a malformed frame; `out` must hold n bytes
static int cobs_decode(const uint8_t *in, uint16_t n, uint8_t *out) {
  uint16_t i = 0, o = 0;
  while (i < n) {
    uint8_t code = in[i];
    if (code == 0 || (uint16_t)(i + code) > n) return -1;
    for (uint8_t k = 1; k < code; k++) { if (in[i + k] == 0) return -1; out[o++] = in[i + k]; }
    i += code;
    if (code != 0xFF && i < n) out[o++] = 0;
  }
  return o;
}

// ---------------------------------------------------------------- little-endian helpers
static void put_u16(uint8_t *p, uint16_t v) { p[0] = v & 0xFF; p[1] = v >> 8; }
static void put_u32(uint8_t *p, uint32_t v) { for (int k = 0; k < 4; k++) p[k] = (v >> (8 * k)) & 0xFF; }
static int16_t get_i16(const uint8_t *p) { return (int16_t)(p[0] | (p[1] << 8)); }
static int16_t sat16(float v) { return v > 32767.0f ? 32767 : (v < -32768.0f ? -32768 : (int16_t)lroundf(v)); }
static uint16_t satu16(float v) { return v > 65535.0f ? 65535 : (v < 0.0f ? 0 : (uint16_t)lroundf(v)); }

static void send_packet(uint8_t type, uint8_t seq, const uint8_t *payload, uint8_t len) {
  uint8_t pkt[MAX_PACKET];
  pkt[0] = PROTO_VERSION; pkt[1] = type; pkt[2] = seq; pkt[3] = len;
  memcpy(pkt + 4, payload, len);
  put_u16(pkt + 4 + len, crc16(pkt, 4 + len));
  uint8_t enc[MAX_ENCODED + 1];                                   // + the delimiter
  uint16_t n = cobs_encode(pkt, 6 + len, enc);
  enc[n++] = 0;
  SerialUSB.write(enc, n);
}

// ---------------------------------------------------------------- hardware (HW: fill in)
static float read_boom_angle() { return 0.0f; }     // HW: encoder counts -> rad, 0 at the attack pose
static float read_bucket_angle() { return 0.0f; }   // HW
static float read_wheel(int which) { (void)which; return 0.0f; }    // HW: motor encoder / gear ratio, rad/s
static float read_current(int which) { (void)which; return 0.0f; }  // HW: current sense, A
static void drive_wheels(float setpoint) { (void)setpoint; }        // HW: speed loop of the three motors
static void drive_valve(int joint, int8_t dir) { (void)joint; (void)dir; }  // HW: solenoid valves
static bool estop_pressed() { return false; }                        // HW

// what the outputs really do, for the sensor frame
struct Outputs { bool run; int8_t boom; int8_t bucket; bool estop; };

static Outputs apply_outputs(float boom_angle, float bucket_angle) {
  bool estop = estop_pressed();
  bool run = cmd.enable && have_cmd && !watchdog_tripped && !estop;
  float w = run ? cmd.wheel : 0.0f;
  if (w < 0.0f) w = 0.0f;
  if (w > WHEEL_MAX) w = WHEEL_MAX;
  int8_t boom = run ? cmd.boom : 0;
  int8_t bucket = run ? cmd.bucket : 0;
  if (!MAINTENANCE_BUILD) { if (boom < 0) boom = 0; if (bucket < 0) bucket = 0; }
  // +1 raises the boom (angle decreases); stop at the joint limits
  if ((boom > 0 && boom_angle <= BOOM_MIN) || (boom < 0 && boom_angle >= BOOM_MAX)) boom = 0;
  if ((bucket > 0 && bucket_angle >= BUCKET_MAX) || (bucket < 0 && bucket_angle <= BUCKET_MIN)) bucket = 0;
  drive_wheels(w);
  drive_valve(0, boom);
  drive_valve(1, bucket);
  Outputs o = {run, boom, bucket, estop};
  return o;
}

// ---------------------------------------------------------------- receive
static void handle_packet(const uint8_t *pkt, int n) {
  if (n < 6) return;
  uint8_t len = pkt[3];
  if (pkt[0] != PROTO_VERSION || len > MAX_PAYLOAD || n != 6 + len) return;
  uint16_t crc = pkt[4 + len] | (pkt[5 + len] << 8);
  if (crc16(pkt, 4 + len) != crc) return;
  const uint8_t *pl = pkt + 4;
  if (pkt[1] == TYPE_COMMAND && len == 5) {
    int8_t boom = (int8_t)pl[2], bucket = (int8_t)pl[3];
    if (boom < -1 || boom > 1 || bucket < -1 || bucket > 1 || pl[4] > 1) return;
    cmd.wheel = get_i16(pl) * 1e-3f;
    cmd.boom = boom; cmd.bucket = bucket; cmd.enable = pl[4] == 1;
    last_cmd_ms = millis();
    have_cmd = true;
    watchdog_tripped = false;   // a fresh valid command re-arms the machine
  } else if (pkt[1] == TYPE_HEARTBEAT && len == 4) {
    // host clock only: nothing to do (the command stream is the watchdog's heartbeat)
  }
}

static void poll_serial() {
  while (SerialUSB.available() > 0) {
    uint8_t b = (uint8_t)SerialUSB.read();
    if (b == 0) {
      if (!rx_discard && rx_len > 0) {
        uint8_t pkt[MAX_ENCODED];
        int n = cobs_decode(rx_buf, rx_len, pkt);
        if (n > 0) handle_packet(pkt, n);
      }
      rx_len = 0; rx_discard = false;
    } else if (!rx_discard) {
      if (rx_len >= MAX_ENCODED) { rx_discard = true; rx_len = 0; }   // overflow: skip to the next 0x00
      else rx_buf[rx_len++] = b;
    }
  }
}

// ---------------------------------------------------------------- main loop
static uint32_t last_sensor_us = 0;
static float prev_boom = 0.0f, prev_bucket = 0.0f;

void setup() {
  SerialUSB.begin(115200);
  drive_wheels(0.0f); drive_valve(0, 0); drive_valve(1, 0);
}

void loop() {
  poll_serial();
  uint32_t now_ms = millis();
  if (have_cmd && (uint32_t)(now_ms - last_cmd_ms) > WATCHDOG_MS && !watchdog_tripped) {
    watchdog_tripped = true;
    cmd.enable = false; cmd.wheel = 0.0f; cmd.boom = 0; cmd.bucket = 0;
  }
  float boom = read_boom_angle(), bucket = read_bucket_angle();
  Outputs out = apply_outputs(boom, bucket);
  uint32_t now_us = micros();
  if ((uint32_t)(now_us - last_sensor_us) >= SENSOR_PERIOD_US) {
    float dt = (now_us - last_sensor_us) * 1e-6f;
    last_sensor_us = now_us;
    uint8_t p[27];
    put_u32(p, now_us);
    put_u16(p + 4, (uint16_t)sat16(boom / 1e-4f));
    put_u16(p + 6, (uint16_t)sat16(bucket / 1e-4f));
    put_u16(p + 8, (uint16_t)sat16((boom - prev_boom) / dt / 1e-4f));
    put_u16(p + 10, (uint16_t)sat16((bucket - prev_bucket) / dt / 1e-4f));
    prev_boom = boom; prev_bucket = bucket;
    for (int k = 0; k < 3; k++) put_u16(p + 12 + 2 * k, (uint16_t)sat16(read_wheel(k) / 1e-3f));
    for (int k = 0; k < 3; k++) put_u16(p + 18 + 2 * k, satu16(read_current(k) / 1e-3f));
    p[24] = (uint8_t)out.boom;      // what the valves do (closed at a limit, on e-stop, ...)
    p[25] = (uint8_t)out.bucket;
    p[26] = (out.run ? 0x01 : 0) | (watchdog_tripped ? 0x02 : 0) | (out.estop ? 0x04 : 0);
    send_packet(TYPE_SENSOR, seq_sensor++, p, sizeof p);
  }
}
