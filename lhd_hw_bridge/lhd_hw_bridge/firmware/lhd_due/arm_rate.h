// A joint's rate over the last RATE_WINDOW_US: (newest angle - the newest angle at least RATE_WINDOW_US
// older) / the time between them; until such a sample exists, the oldest kept stands in (0 with one
// sample). The same as lhd_loading_ros/task/arm_sensors.py RateWindow (test/hw_bridge/test_arm_rate.py
// runs both on the same samples).
//
// Why a window and not one sensor frame: one 10 ms frame turns 0.1 deg of noise on the angle into
// 0.25 rad/s of rate noise, more than the hydraulics' full speed (0.19-0.2 rad/s); over the 0.1 s the
// policy decides on, 0.025 rad/s (docs/training.md "The arm's rates").
#pragma once
#include <stdint.h>

#ifndef RATE_WINDOW_US
#define RATE_WINDOW_US 100000UL   // one control period (10 Hz); RATE_WINDOW_S in arm_sensors.py
#endif
#define RATE_RING 32              // samples kept at most: > RATE_WINDOW_US / the sensor period + 1

struct RateWindow {
  uint32_t t_us[RATE_RING];
  float angle[RATE_RING];
  uint8_t first, count;           // the oldest kept sample and how many are kept
};

static inline void rate_window_reset(RateWindow *w) { w->first = 0; w->count = 0; }

static inline float rate_window_push(RateWindow *w, uint32_t t_us, float angle) {
  if (w->count == RATE_RING) { w->first = (uint8_t)((w->first + 1) % RATE_RING); w->count--; }
  uint8_t last = (uint8_t)((w->first + w->count) % RATE_RING);
  w->t_us[last] = t_us;
  w->angle[last] = angle;
  w->count++;
  // drop the oldest while the next one is itself at least a window old (wrap-safe differences)
  while (w->count >= 2 && (uint32_t)(t_us - w->t_us[(w->first + 1) % RATE_RING]) >= RATE_WINDOW_US) {
    w->first = (uint8_t)((w->first + 1) % RATE_RING);
    w->count--;
  }
  uint32_t dt = t_us - w->t_us[w->first];
  return dt == 0 ? 0.0f : (angle - w->angle[w->first]) / ((float)dt * 1e-6f);
}
