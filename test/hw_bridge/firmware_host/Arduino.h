// Arduino.h for running lhd_due.ino on a Linux host in the tests (test_hw_doc_interop.py):
// SerialUSB reads stdin and writes stdout (the test connects both to a pseudo-terminal),
// millis()/micros() come from the monotonic clock, and the pin functions drive a simulated HX711
// load-cell amplifier wired where the test says (hx711_sim.h). Only what the firmware uses.
#pragma once
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <atomic>
#include <thread>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

#include "hx711_sim.h"

inline uint32_t micros() {
  timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (uint32_t)(t.tv_sec * 1000000ull + t.tv_nsec / 1000);
}
inline uint32_t millis() { return micros() / 1000; }

// LHD_HOST_USB_STALL_FILE (environment): while that file exists, write() waits, as the SAM core's
// UDD_Send waits with no time limit for the host to collect the previous USB packet (a pulled
// cable, a host that stopped reading). Only the SAM3X watchdog below gets the device out of it.
struct HostSerial {
  const char *stall_file = getenv("LHD_HOST_USB_STALL_FILE");
  void begin(unsigned long) {}
  int available() { int n = 0; return ioctl(0, FIONREAD, &n) == 0 ? n : 0; }
  int read() { uint8_t b; return ::read(0, &b, 1) == 1 ? b : -1; }
  size_t write(const uint8_t *d, size_t n) {
    while (stall_file != nullptr && access(stall_file, F_OK) == 0) usleep(1000);
    return ::write(1, d, n) == (ssize_t)n ? n : 0;
  }
};
static HostSerial SerialUSB;

// The SAM3X watchdog (Arduino SAM core: watchdogEnable / watchdogReset; init() calls the sketch's
// watchdogSetup() before setup(): main.cpp does). With LHD_HOST_WATCHDOG_RESET=1 a thread resets
// the "chip" when watchdogReset() was not called for the timeout: it re-executes this program
// (every variable back to its initial value, as a reset does; the pseudo-terminal stays) and says
// "host-wdt: reset" on stderr. Without it the watchdog does nothing: the other tests' hosts may be
// preempted for longer than the device's 100 ms.
static std::atomic<uint32_t> host_wdt_fed_ms{0};
inline void watchdogReset() { host_wdt_fed_ms = millis(); }
inline void watchdogEnable(uint32_t timeout_ms) {
  const char *on = getenv("LHD_HOST_WATCHDOG_RESET");
  if (on == nullptr || strcmp(on, "1") != 0) return;
  host_wdt_fed_ms = millis();
  std::thread([timeout_ms] {
    for (;;) {
      usleep(2000);
      if ((uint32_t)(millis() - host_wdt_fed_ms) > timeout_ms) {
        fprintf(stderr, "host-wdt: reset\n");
        fflush(stderr);
        char self[] = "/proc/self/exe";
        char *argv[] = {self, nullptr};
        execv(self, argv);
        _exit(99);
      }
    }
  }).detach();
}

// ---------------------------------------------------------------- digital pins (as the Arduino core names them)
#define LOW 0x0
#define HIGH 0x1
#define INPUT 0x0
#define OUTPUT 0x1
#define INPUT_PULLUP 0x2

static bool host_interrupts_enabled = true;
static uint8_t host_pin_mode[128];
inline void noInterrupts() { host_interrupts_enabled = false; }
inline void interrupts() { host_interrupts_enabled = true; }
inline void pinMode(uint32_t pin, uint32_t mode) { if (pin < 128) host_pin_mode[pin] = (uint8_t)mode; }
inline void digitalWrite(uint32_t pin, uint32_t val) {
  if ((int)pin == hx711_sim.sck_pin && host_pin_mode[pin] == OUTPUT) hx711_sim.write_sck(val != LOW, host_interrupts_enabled);
}
// an unconnected input with its pull-up reads HIGH (without: LOW here; a real one floats)
inline int digitalRead(uint32_t pin) {
  if ((int)pin == hx711_sim.dout_pin) return hx711_sim.read_dout() ? HIGH : LOW;
  return pin < 128 && host_pin_mode[pin] == INPUT_PULLUP ? HIGH : LOW;
}
// a busy wait, as on the Arduino (a sleep would take tens of microseconds for one)
inline void delayMicroseconds(unsigned int us) {
  hx711_sim.delay_us(us);
  uint32_t t0 = micros();
  while ((uint32_t)(micros() - t0) < us) {}
}
