#include "check.h"

#include <string.h>

namespace check {

int failures = 0;
int checks = 0;

namespace {
struct Entry {
  const char* name;
  TestFn fn;
};
Entry registry[256];
int count = 0;
}  // namespace

Registration::Registration(const char* name, TestFn fn) {
  if (count < 256) {
    registry[count].name = name;
    registry[count].fn = fn;
    ++count;
  }
}

int run_all(const char* filter) {
  int ran = 0;
  for (int i = 0; i < count; ++i) {
    if (filter && !strstr(registry[i].name, filter)) continue;
    const int before = failures;
    registry[i].fn();
    ++ran;
    printf("%s %s\n", failures == before ? "ok  " : "FAIL", registry[i].name);
  }
  printf("%d tests, %d checks, %d failures\n", ran, checks, failures);
  return failures == 0 && ran > 0 ? 0 : 1;
}

}  // namespace check
