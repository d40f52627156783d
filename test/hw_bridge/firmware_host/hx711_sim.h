// A simulated HX711 load-cell amplifier on two pins of the host build (Arduino.h routes
// pinMode / digitalWrite / digitalRead / delayMicroseconds / noInterrupts here). Written from the
// HX711 datasheet, not from the firmware:
// * DOUT high = no conversion ready; low = one is ready. Each rising edge of PD_SCK shifts out
//   the next of 24 bits, MSB first, two's complement; the 25th rising edge pulls DOUT high again.
//   25 pulses in all select channel A, gain 128 for the next conversion, 26 channel B, gain 32,
//   27 channel A, gain 64.
// * The output saturates: an input beyond full scale gives 0x7FFFFF (or 0x800000 below).
// * PD_SCK high for more than 60 us powers the chip down; when it goes low the chip powers up
//   reset (channel A, gain 128) and its first conversion comes after the settling time (4
//   conversion periods: 400 ms at 10 samples/s, 50 ms at 80).
//
// Time while PD_SCK is high is counted from delayMicroseconds() only: the host can preempt the
// process anywhere, which would make a wall-clock rule flaky. What a preemption stands for on
// the Due, an interrupt inside a pulse, is checked instead: a short pulse (a read) with
// interrupts enabled is reported as a violation.
//
// Environment, set by the test: HX711_SIM_DOUT_PIN, HX711_SIM_SCK_PIN (where the test wired the
// chip: unset, no chip), HX711_SIM_FILE (read at each conversion: "COUNTS [A]", the input in
// counts at gain 128, plus, with A, A x (2 (k mod 16) - 15) at conversion k: a ramp whose every
// 16 consecutive values sum to 0, so only a mean over 16 conversions gives COUNTS exactly; or
// "off": the chip stops converting, as when unplugged), HX711_SIM_SPS (10 or 80).
// Events go to stderr, one line each, prefixed "hx711-sim:".
#pragma once
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

class Hx711Sim {
 public:
  int dout_pin = -1, sck_pin = -1;

  void init() {
    const char *d = getenv("HX711_SIM_DOUT_PIN"), *s = getenv("HX711_SIM_SCK_PIN");
    file_ = getenv("HX711_SIM_FILE");
    const char *sps = getenv("HX711_SIM_SPS");
    if (d && s && file_) {
      dout_pin = atoi(d);
      sck_pin = atoi(s);
    }
    period_us_ = 1000000ull / (uint64_t)(sps ? atoi(sps) : 10);
    next_us_ = now_us() + 4 * period_us_;     // power-on: settling before the first conversion
  }

  bool read_dout() {
    update();
    return dout_;
  }

  void write_sck(bool high, bool interrupts_enabled) {
    update();
    if (high == sck_) return;
    sck_ = high;
    if (high) {
      high_us_ = 0;
      pulse_with_interrupts_ = interrupts_enabled;
      if (!powered_ || !reading_) return;
      pulses_++;
      if (pulses_ <= 24) dout_ = (word_ >> (24 - pulses_)) & 1;
      else dout_ = true;                      // 25th edge: DOUT back high until the next conversion
      return;
    }
    if (!powered_) {                          // low after a power-down: power up, reset
      powered_ = true;
      gain_pulses_ = 25;
      reading_ = false;
      pulses_ = 0;
      dout_ = true;
      next_us_ = now_us() + 4 * period_us_;
      log("power up (reset: channel A, gain 128)");
      return;
    }
    if (reading_ && pulse_with_interrupts_) {
      violations++;
      log("SCK pulse with interrupts enabled (an interrupt could stretch it past 60 us)");
    }
  }

  void delay_us(unsigned int us) {
    if (!sck_ || !powered_) return;
    high_us_ += us;
    if (high_us_ > 60) {
      powered_ = false;
      power_downs++;
      if (reading_ && pulses_ < 25) log("power down in the middle of a read");
      reading_ = false;
      pulses_ = 0;
      dout_ = true;
      log("power down");
    }
  }

  int power_downs = 0, violations = 0;

 private:
  const char *file_ = nullptr;
  uint64_t period_us_ = 100000, next_us_ = 0, high_us_ = 0;
  bool sck_ = false, powered_ = true, dout_ = true, reading_ = false, pulse_with_interrupts_ = false;
  int pulses_ = 0, gain_pulses_ = 25;
  long long conversions_ = 0;
  uint32_t word_ = 0;

  static uint64_t now_us() {
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1000000ull + t.tv_nsec / 1000;
  }

  void log(const char *what) { fprintf(stderr, "hx711-sim: %s\n", what); }

  void update() {
    if (dout_pin < 0 || !powered_ || sck_) return;
    uint64_t now = now_us();
    if (now < next_us_) return;
    if (reading_ && pulses_ > 0 && pulses_ < 25) return;   // a read in progress finishes first
    if (reading_ && pulses_ >= 25) {
      if (pulses_ != 25) {
        char m[96];
        snprintf(m, sizeof m, "read with %d pulses: next conversion not channel A, gain 128", pulses_);
        log(m);
      }
      gain_pulses_ = pulses_ > 27 ? 25 : pulses_;
    }
    while (next_us_ <= now) next_us_ += period_us_;
    long long input = 0;
    if (!read_input(&input)) {                 // "off": no conversion, DOUT stays high
      reading_ = false;
      pulses_ = 0;
      dout_ = true;
      return;
    }
    // channel A gain 128 is the reference; gain 64 halves the counts; channel B reads nothing here
    conversions_++;
    long long v = gain_pulses_ == 25 ? input : (gain_pulses_ == 27 ? input / 2 : 0);
    if (v > 0x7FFFFF) v = 0x7FFFFF;
    if (v < -0x800000) v = -0x800000;
    word_ = (uint32_t)v & 0xFFFFFF;
    reading_ = true;
    pulses_ = 0;
    dout_ = false;                             // ready
  }

  bool read_input(long long *out) {
    FILE *f = fopen(file_, "r");
    if (!f) return false;
    char buf[64] = {0};
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    if (strncmp(buf, "off", 3) == 0) return false;
    char *end = nullptr, *end2 = nullptr;
    *out = strtoll(buf, &end, 10);
    if (end == buf) return false;
    long long ramp = strtoll(end, &end2, 10);
    if (end2 != end) *out += ramp * (2 * (conversions_ % 16) - 15);
    return true;
  }
};

static Hx711Sim hx711_sim;
