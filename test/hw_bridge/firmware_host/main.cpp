// The Arduino runtime's main(), on a host: setup() once, then loop() (with a short sleep so the
// test machine's cores stay free; the sensor period is 10 ms).
#include "Arduino.h"
#include "lhd_due.ino"

int main() {
  setup();
  for (;;) { loop(); usleep(200); }
}
