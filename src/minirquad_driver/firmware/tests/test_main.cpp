// Host unit tests of the firmware core: test_core GOLDEN_FILE [name-filter]
#include <stdio.h>

#include "check.h"

const char* g_golden_path = 0;

int main(int argc, char** argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: %s golden_frames.txt [filter]\n", argv[0]);
    return 2;
  }
  g_golden_path = argv[1];
  return check::run_all(argc > 2 ? argv[2] : 0);
}
