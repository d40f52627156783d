// Drives arm_rate.h on a host: reads "t_us angle" lines from stdin, prints the rate after each.
#include <stdio.h>
#include "arm_rate.h"

int main() {
  RateWindow w;
  rate_window_reset(&w);
  unsigned long t;
  float a;
  while (scanf("%lu %f", &t, &a) == 2) printf("%.9g\n", (double)rate_window_push(&w, (uint32_t)t, a));
  return 0;
}
