// lhd_due.ino -- reference firmware for the scaled LHD's Arduino Due (device side of
// docs/serial_protocol.md, version 1). Keep in step with that document and with
// lhd_hw_bridge/fake_due.py (the emulator the tests run against).
//
// It cannot be compiled in CI (no Arduino toolchain there). Pin numbers, encoder scaling and
// the motor/valve drivers are placeholders marked HW: to be set for the machine. The tests
// compile it on the host instead (test/hw_bridge/firmware_host/: the Arduino API, and an HX711
// on two pins, simulated).
//
// Optional: the bucket's load cell through an HX711 amplifier. Define LHD_HAS_LOAD_CELL (here, or
// -DLHD_HAS_LOAD_CELL) and the device also sends load-cell frames (type 0x04) at 10 Hz; wiring
// and calibration (LOAD_CELL_OFFSET, LOAD_CELL_SCALE below) in docs/hardware_bridge.md.
// #define LHD_HAS_LOAD_CELL

#include <Arduino.h>
#include <string.h>
#include "arm_rate.h"          // the boom and bucket rates over the last 0.1 s, not one frame

// ---------------------------------------------------------------- protocol constants
static const uint8_t PROTO_VERSION = 1;
static const uint8_t TYPE_SENSOR = 0x01;
static const uint8_t TYPE_COMMAND = 0x02;
static const uint8_t TYPE_HEARTBEAT = 0x03;
static const uint8_t MAX_PAYLOAD = 64;
static const uint16_t MAX_PACKET = 4 + MAX_PAYLOAD + 2;              // 70 bytes
static const uint16_t MAX_ENCODED = MAX_PACKET + 1 + MAX_PACKET / 255; // 71: largest COBS frame, without its 0x00

static const uint32_t SENSOR_PERIOD_US = 10000;   // 100 Hz
static_assert(RATE_WINDOW_US / SENSOR_PERIOD_US + 2 <= RATE_RING,
              "arm_rate.h keeps too few samples for RATE_WINDOW_US at this sensor period: raise RATE_RING");
static const uint32_t WATCHDOG_MS = 250;          // stop when command frames stop
// The SAM3X's own watchdog: resets the Due when loop() stops for this long. loop() can stop inside
// SerialUSB.write(), which waits with no time limit for the host to collect the previous USB packet
// (a cable pulled while the Due is powered from the machine): then neither the 250 ms watchdog
// above nor the emergency-stop input would run again. After the reset setup() drives every output
// off and the device holds the machine stopped until a stop frame (flag bit 3).
#ifndef HW_WATCHDOG_MS
#define HW_WATCHDOG_MS 100
#endif
static const uint16_t MAX_RX_PER_LOOP = 128;      // bytes taken per loop(): a flood of input cannot starve it
static const float WHEEL_MAX = 2.7f;              // rad/s
static const float BOOM_MIN = -1.0f, BOOM_MAX = 0.05f;      // rad, joint limits
static const float BUCKET_MIN = -0.1f, BUCKET_MAX = 1.4f;   // rad
// an arm angle further than this beyond its joint's limits is no reading (a broken wire reads a
// rail, a failed conversion NaN): a sensor fault, flag bit 4, every output stopped. So is a NaN
// wheel speed or motor current
static const float ANGLE_PLAUSIBLE_MARGIN = 0.3f;           // rad
static const bool MAINTENANCE_BUILD = false;      // true allows lowering / forward tilt

// ---------------------------------------------------------------- state
struct Command { float wheel; int8_t boom; int8_t bucket; bool enable; };
static Command cmd = {0.0f, 0, 0, false};
static uint32_t last_cmd_ms = 0;
static bool have_cmd = false;
static bool watchdog_tripped = false;
// held: the machine stays stopped, whatever the commands say, until a command frame with enable = 0
// arrives with no emergency stop and no sensor fault. Set at power-up and every reset, while the
// emergency stop is pressed and while an arm angle is faulty: releasing the emergency stop, or a
// sensor that reads again, never restarts the machine by itself (ISO 13850: resetting an
// emergency stop must not restart the machine). The host's stop frames clear it (the first frame
// after it opens the port is a stop); flag bit 3.
static bool held = true;
static bool was_reset = true;      // from power-up or any reset until the first stop frame: flag bit 5
static bool sensor_fault = false;  // this loop: an arm angle is no reading, or the last frame's readings had a NaN
static bool reading_fault = false; // this loop read a NaN wheel speed or current
// sequence numbers: one counter per frame type this device sends (docs/serial_protocol.md):
// this one for sensor frames, seq_load_cell for load-cell frames (LHD_HAS_LOAD_CELL)
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
// NaN (a failed reading) goes out as the field's sentinel, -32768 / 65535 (lroundf(NaN) is undefined)
static int16_t sat16(float v) {
  if (!(v == v)) return -32768;
  return v > 32767.0f ? 32767 : (v < -32768.0f ? -32768 : (int16_t)lroundf(v));
}
static uint16_t satu16(float v) {
  if (!(v == v)) return 65535;
  return v > 65535.0f ? 65535 : (v < 0.0f ? 0 : (uint16_t)lroundf(v));
}

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
#ifdef LHD_HOST_IO
#include "host_io.h"         // the tests' host build: angles and the e-stop set by the test, outputs logged
#else
// An angle that cannot be read (a failed conversion, an encoder error) should come back as NAN: it
// stops the machine (sensor fault). A raw ADC value at a rail should too (a broken wire).
static float read_boom_angle() { return 0.0f; }     // HW: encoder counts -> rad, 0 at the attack pose
static float read_bucket_angle() { return 0.0f; }   // HW
static float read_wheel(int which) { (void)which; return 0.0f; }    // HW: motor encoder / gear ratio, rad/s
static float read_current(int which) { (void)which; return 0.0f; }  // HW: current sense, A
static void drive_wheels(float setpoint) { (void)setpoint; }        // HW: speed loop of the three motors
static void drive_valve(int joint, int8_t dir) { (void)joint; (void)dir; }  // HW: solenoid valves
static bool estop_pressed() { return false; }                        // HW
#endif

// the SAM3X watchdog (Arduino SAM core: its main() calls watchdogSetup() before init() and setup(); the
// core's default switches the watchdog off, and its mode register can be written once per reset)
void watchdogSetup(void) { watchdogEnable(HW_WATCHDOG_MS); }

// NaN fails: a NaN angle is not plausible
static bool angle_plausible(float a, float lo, float hi) {
  return a >= lo - ANGLE_PLAUSIBLE_MARGIN && a <= hi + ANGLE_PLAUSIBLE_MARGIN;
}

// what the outputs really do, for the sensor frame
struct Outputs { bool run; int8_t boom; int8_t bucket; bool estop; };

static const Command STOP_COMMAND = {0.0f, 0, 0, false};

static Outputs apply_outputs(float boom_angle, float bucket_angle) {
  bool estop = estop_pressed();
  sensor_fault = !angle_plausible(boom_angle, BOOM_MIN, BOOM_MAX) ||
                 !angle_plausible(bucket_angle, BUCKET_MIN, BUCKET_MAX) || reading_fault;
  if (estop || sensor_fault) {
    held = true;
    cmd = STOP_COMMAND;        // nothing of the command before it is kept
  }
  bool run = cmd.enable && have_cmd && !watchdog_tripped && !estop && !held && !sensor_fault;
  float w = run ? cmd.wheel : 0.0f;
  if (w < 0.0f) w = 0.0f;
  if (w > WHEEL_MAX) w = WHEEL_MAX;
  int8_t boom = run ? cmd.boom : 0;
  int8_t bucket = run ? cmd.bucket : 0;
  if (!MAINTENANCE_BUILD) { if (boom < 0) boom = 0; if (bucket < 0) bucket = 0; }
  // +1 raises the boom (angle decreases); stop at the joint limits. Written so that a NaN angle
  // fails the test and closes the valve (a review: `boom_angle <= BOOM_MIN` is false for NaN)
  if ((boom > 0 && !(boom_angle > BOOM_MIN)) || (boom < 0 && !(boom_angle < BOOM_MAX))) boom = 0;
  if ((bucket > 0 && !(bucket_angle < BUCKET_MAX)) || (bucket < 0 && !(bucket_angle > BUCKET_MIN))) bucket = 0;
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
    watchdog_tripped = false;   // a fresh valid command re-arms the machine after a lost link
    // a stop frame clears the hold (power-up, e-stop released, sensor reading again), not motion
    if (!cmd.enable && !estop_pressed() && !sensor_fault) { held = false; was_reset = false; }
  } else if (pkt[1] == TYPE_HEARTBEAT && len == 4) {
    // host clock only: nothing to do (the command stream is the watchdog's heartbeat)
  }
}

static void poll_serial() {
  for (uint16_t taken = 0; taken < MAX_RX_PER_LOOP && SerialUSB.available() > 0; taken++) {
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

// ---------------------------------------------------------------- load cell (optional)
#ifdef LHD_HAS_LOAD_CELL
// Wiring (docs/hardware_bridge.md, "Load cell"): HX711 module powered from the Due's 3.3 V (its
// DOUT then drives 3.3 V logic: the Due's pins are not 5 V tolerant), RATE low (10 samples/s).
#ifndef LOAD_CELL_DOUT_PIN
#define LOAD_CELL_DOUT_PIN 22      // HX711 DOUT (DT): input, with the Due's pull-up (unplugged reads "not ready")
#endif
#ifndef LOAD_CELL_SCK_PIN
#define LOAD_CELL_SCK_PIN 23       // HX711 PD_SCK: output, kept low between reads
#endif
// Calibration (docs/hardware_bridge.md, "Load cell", "Calibration"):
// LOAD_CELL_SCALE: counts per kg in the bucket, (raw with a known mass - raw empty) / known mass.
//   Left at 0 the device is "not calibrated": its frames carry raw counts and a mass of 0.
// LOAD_CELL_OFFSET: raw counts with the bucket empty. Left undefined, the device tares itself:
//   the mean of its first LOAD_CELL_TARE_SAMPLES conversions after power-up (bucket empty then).
#ifndef LOAD_CELL_SCALE
#define LOAD_CELL_SCALE 0.0f
#endif
#ifndef LOAD_CELL_TARE_SAMPLES
#define LOAD_CELL_TARE_SAMPLES 16  // 1.6 s at 10 samples/s
#endif
static const uint8_t TYPE_LOAD_CELL = 0x04;
static const uint32_t LOAD_CELL_PERIOD_US = 100000;   // 10 Hz frames
static const uint32_t LOAD_CELL_STALE_MS = 500;       // no conversion for this long: stale, power-cycle the HX711
static const int32_t HX711_MAX = 8388607L, HX711_MIN = -8388608L;   // its output at and beyond full scale

static int32_t lc_raw = 0;             // latest conversion, counts
static uint32_t lc_time_us = 0;        // when it was read
static uint32_t lc_last_ms = 0;
static bool lc_have = false;           // a conversion since power-up
static uint32_t lc_reset_ms = 0;       // last power cycle of the HX711
static uint32_t lc_last_frame_us = 0;
#ifdef LOAD_CELL_OFFSET
static int32_t lc_offset = LOAD_CELL_OFFSET;
static bool lc_tared = true;
#else
static int32_t lc_offset = 0;
static bool lc_tared = false;
#endif
static int64_t lc_tare_sum = 0;
static uint16_t lc_tare_n = 0;
static uint8_t seq_load_cell = 0;      // load-cell frames have their own sequence counter

// SCK high for more than 60 us powers the HX711 down; back low, it powers up reset (channel A,
// gain 128) and settles (400 ms at 10 samples/s) before its first conversion.
static void hx711_power_cycle(uint32_t now_ms) {
  digitalWrite(LOAD_CELL_SCK_PIN, HIGH);
  delayMicroseconds(100);
  digitalWrite(LOAD_CELL_SCK_PIN, LOW);
  lc_reset_ms = now_ms;
}

// Only when DOUT is low (a conversion is ready): 24 bits MSB first, each shifted out on a rising
// edge of SCK, then a 25th pulse that selects channel A, gain 128 for the next conversion. About
// 75 us on the Due. Interrupts are off while SCK is high: an interrupt there could stretch the
// pulse past 60 us and power the HX711 down in the middle of a read.
static int32_t hx711_read() {
  uint32_t v = 0;
  for (uint8_t i = 0; i < 25; i++) {
    noInterrupts();
    digitalWrite(LOAD_CELL_SCK_PIN, HIGH);
    delayMicroseconds(1);              // DOUT is valid 0.1 us after the rising edge
    if (i < 24) v = (v << 1) | (digitalRead(LOAD_CELL_DOUT_PIN) == HIGH ? 1u : 0u);
    digitalWrite(LOAD_CELL_SCK_PIN, LOW);
    interrupts();
    delayMicroseconds(1);
  }
  if (v & 0x800000UL) v |= 0xFF000000UL;   // 24-bit two's complement -> 32 bits
  return (int32_t)v;
}

static void load_cell_setup() {
  pinMode(LOAD_CELL_DOUT_PIN, INPUT_PULLUP);
  pinMode(LOAD_CELL_SCK_PIN, OUTPUT);
  digitalWrite(LOAD_CELL_SCK_PIN, LOW);
  hx711_power_cycle(millis());         // a known state, whatever it was doing when the Due reset
}

// Once per loop, never waits: reads a conversion only when DOUT says one is ready.
static void load_cell_poll(uint32_t now_ms, uint32_t now_us) {
  if (digitalRead(LOAD_CELL_DOUT_PIN) == LOW) {
    lc_raw = hx711_read();
    lc_time_us = now_us;
    lc_last_ms = now_ms;
    lc_have = true;
    if (!lc_tared && lc_raw != HX711_MAX && lc_raw != HX711_MIN) {
      lc_tare_sum += lc_raw;
      if (++lc_tare_n >= LOAD_CELL_TARE_SAMPLES) {
        lc_offset = (int32_t)(lc_tare_sum / lc_tare_n);
        lc_tared = true;
      }
    }
  } else if ((uint32_t)(now_ms - (lc_have ? lc_last_ms : lc_reset_ms)) > LOAD_CELL_STALE_MS &&
             (uint32_t)(now_ms - lc_reset_ms) > LOAD_CELL_STALE_MS) {
    hx711_power_cycle(now_ms);         // silent for 500 ms: reset it, at most every 500 ms
  }
}

static void load_cell_send(uint32_t now_ms) {
  const bool calibrated = LOAD_CELL_SCALE != 0.0f;
  const bool stale = !lc_have || (uint32_t)(now_ms - lc_last_ms) > LOAD_CELL_STALE_MS;
  const bool saturated = lc_raw == HX711_MAX || lc_raw == HX711_MIN;
  float grams = 0.0f;
  if (calibrated && lc_tared && lc_have) grams = (float)(lc_raw - lc_offset) / (LOAD_CELL_SCALE * 1e-3f);
  int32_t mass = grams > 2147483520.0f ? 2147483647L : (grams < -2147483520.0f ? -2147483647L - 1 : (int32_t)lroundf(grams));
  uint8_t p[13];
  put_u32(p, lc_time_us);
  put_u32(p + 4, (uint32_t)mass);
  put_u32(p + 8, (uint32_t)lc_raw);
  p[12] = (calibrated ? 0x01 : 0) | (lc_tared ? 0x02 : 0) | (saturated ? 0x04 : 0) | (stale ? 0x08 : 0);
  send_packet(TYPE_LOAD_CELL, seq_load_cell++, p, sizeof p);
}
#endif

// ---------------------------------------------------------------- main loop
static uint32_t last_sensor_us = 0;
static RateWindow boom_rate_window, bucket_rate_window;   // arm_rate.h: the rates over the last 0.1 s

void setup() {
  drive_wheels(0.0f); drive_valve(0, 0); drive_valve(1, 0);   // first: outputs off, held (see `held`)
  SerialUSB.begin(115200);
#ifdef LHD_HAS_LOAD_CELL
  load_cell_setup();
#endif
}

void loop() {
  watchdogReset();
  poll_serial();
  uint32_t now_ms = millis();
  if (have_cmd && (uint32_t)(now_ms - last_cmd_ms) > WATCHDOG_MS && !watchdog_tripped) {
    watchdog_tripped = true;
    cmd.enable = false; cmd.wheel = 0.0f; cmd.boom = 0; cmd.bucket = 0;
  }
  float boom = read_boom_angle(), bucket = read_bucket_angle();
  // every reading before the outputs: a NaN wheel speed or current stops them in this loop, and the frame
  // that reports the fault already shows them stopped (a review: it showed both valves still open)
  float wheel[3], current[3];
  bool nan_reading = false;
  for (int k = 0; k < 3; k++) {
    wheel[k] = read_wheel(k);
    current[k] = read_current(k);
    nan_reading = nan_reading || !(wheel[k] == wheel[k]) || !(current[k] == current[k]);
  }
  reading_fault = nan_reading;
  Outputs out = apply_outputs(boom, bucket);
  uint32_t now_us = micros();
  if ((uint32_t)(now_us - last_sensor_us) >= SENSOR_PERIOD_US) {
    last_sensor_us = now_us;
    uint8_t p[27];
    put_u32(p, now_us);
    put_u16(p + 4, (uint16_t)sat16(boom / 1e-4f));
    put_u16(p + 6, (uint16_t)sat16(bucket / 1e-4f));
    float boom_rate = NAN, bucket_rate = NAN;
    if (sensor_fault) {
      // a faulty angle never enters the rate windows: they start afresh once the angles read again (a
      // review: a NaN or rail sample kept the rates at -3.3 rad/s for a window after the fault cleared)
      rate_window_reset(&boom_rate_window);
      rate_window_reset(&bucket_rate_window);
    } else {
      boom_rate = rate_window_push(&boom_rate_window, now_us, boom);
      bucket_rate = rate_window_push(&bucket_rate_window, now_us, bucket);
    }
    put_u16(p + 8, (uint16_t)sat16(boom_rate / 1e-4f));
    put_u16(p + 10, (uint16_t)sat16(bucket_rate / 1e-4f));
    for (int k = 0; k < 3; k++) {
      put_u16(p + 12 + 2 * k, (uint16_t)sat16(wheel[k] / 1e-3f));
      put_u16(p + 18 + 2 * k, satu16(current[k] / 1e-3f));
    }
    p[24] = (uint8_t)out.boom;      // what the valves do (closed at a limit, on e-stop, ...)
    p[25] = (uint8_t)out.bucket;
    p[26] = (out.run ? 0x01 : 0) | (watchdog_tripped ? 0x02 : 0) | (out.estop ? 0x04 : 0) | (held ? 0x08 : 0) |
            (sensor_fault ? 0x10 : 0) | (was_reset ? 0x20 : 0);
    send_packet(TYPE_SENSOR, seq_sensor++, p, sizeof p);
  }
#ifdef LHD_HAS_LOAD_CELL
  load_cell_poll(millis(), micros());
  now_us = micros();
  if ((uint32_t)(now_us - lc_last_frame_us) >= LOAD_CELL_PERIOD_US) {
    lc_last_frame_us = now_us;
    load_cell_send(millis());
  }
#endif
}
