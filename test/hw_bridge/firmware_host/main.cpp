// The Arduino runtime's main(), on a host: watchdogSetup() and setup() once, then loop() (with a short sleep so the
// test machine's cores stay free; the sensor period is 10 ms). The simulated HX711 is wired
// first (hx711_sim.h: from the environment; without it, no chip on any pin).
#include "Arduino.h"
#include "lhd_due.ino"

int main() {
  hx711_sim.init();
  watchdogSetup();           // as the SAM core's init() does, before setup()
  setup();
  for (;;) { loop(); usleep(200); }
}
