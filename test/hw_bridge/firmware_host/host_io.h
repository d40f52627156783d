// The firmware's hardware functions on the host, for the tests that build with -DLHD_HOST_IO
// (test_firmware_safety.py): the arm angles and the e-stop come from the file named by
// LHD_HOST_IO_FILE (lines "boom <rad|nan>", "bucket <rad|nan>", "wheel <rad/s|nan>" (front left),
// "estop <0|1>"; read again at most
// every 2 ms), and every change of the outputs goes to stderr as one line
// "outputs wheel=<rad/s> boom=<-1|0|1> bucket=<-1|0|1>" (the first call always), so a test sees
// what the motors and valves would do even while the device sends nothing.
#pragma once
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct HostIo {
  float boom = 0.0f, bucket = 0.0f, wheel = 0.0f;
  bool estop = false;
  uint32_t read_us = 0;
  bool read_once = false;
  float wheel_out = -1.0f;
  int8_t valve_out[2] = {9, 9};
  bool said = false;

  void refresh() {
    uint32_t now = micros();
    if (read_once && (uint32_t)(now - read_us) < 2000) return;
    read_once = true;
    read_us = now;
    const char *path = getenv("LHD_HOST_IO_FILE");
    if (path == nullptr) return;
    FILE *f = fopen(path, "r");
    if (f == nullptr) return;
    char key[16], val[32];
    while (fscanf(f, "%15s %31s", key, val) == 2) {
      float v = strcmp(val, "nan") == 0 ? NAN : strtof(val, nullptr);
      if (strcmp(key, "boom") == 0) boom = v;
      else if (strcmp(key, "bucket") == 0) bucket = v;
      else if (strcmp(key, "wheel") == 0) wheel = v;
      else if (strcmp(key, "estop") == 0) estop = v != 0.0f;
    }
    fclose(f);
  }
  void outputs_changed() {
    fprintf(stderr, "outputs wheel=%.3f boom=%d bucket=%d\n", wheel_out, valve_out[0], valve_out[1]);
    fflush(stderr);
  }
};
static HostIo host_io;

static float read_boom_angle() { host_io.refresh(); return host_io.boom; }
static float read_bucket_angle() { host_io.refresh(); return host_io.bucket; }
static float read_wheel(int which) { host_io.refresh(); return which == 0 ? host_io.wheel : 0.0f; }
static float read_current(int which) { (void)which; return 0.0f; }
static bool estop_pressed() { host_io.refresh(); return host_io.estop; }
static void drive_wheels(float setpoint) {
  if (setpoint != host_io.wheel_out) { host_io.wheel_out = setpoint; host_io.said = false; }
}
static void drive_valve(int joint, int8_t dir) {
  if (dir != host_io.valve_out[joint]) { host_io.valve_out[joint] = dir; host_io.said = false; }
  if (joint == 1 && !host_io.said) { host_io.said = true; host_io.outputs_changed(); }
}
