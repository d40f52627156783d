// Arduino.h for running lhd_due.ino on a Linux host in the tests (test_firmware_host.py):
// SerialUSB reads stdin and writes stdout (the test connects both to a pseudo-terminal),
// millis()/micros() come from the monotonic clock. Only what the firmware uses.
#pragma once
#include <math.h>
#include <stdint.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

inline uint32_t micros() {
  timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (uint32_t)(t.tv_sec * 1000000ull + t.tv_nsec / 1000);
}
inline uint32_t millis() { return micros() / 1000; }

struct HostSerial {
  void begin(unsigned long) {}
  int available() { int n = 0; return ioctl(0, FIONREAD, &n) == 0 ? n : 0; }
  int read() { uint8_t b; return ::read(0, &b, 1) == 1 ? b : -1; }
  size_t write(const uint8_t *d, size_t n) { return ::write(1, d, n) == (ssize_t)n ? n : 0; }
};
static HostSerial SerialUSB;
