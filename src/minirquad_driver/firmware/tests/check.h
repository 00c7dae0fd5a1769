// A minimal test harness (no third-party framework: the host build needs only g++).
#ifndef MRQ_TESTS_CHECK_H
#define MRQ_TESTS_CHECK_H

#include <stdio.h>
#include <stdlib.h>

namespace check {

extern int failures;
extern int checks;

typedef void (*TestFn)();
struct Registration {
  Registration(const char* name, TestFn fn);
};
int run_all(const char* filter);

}  // namespace check

#define CHECK(cond)                                                              \
  do {                                                                           \
    ++check::checks;                                                             \
    if (!(cond)) {                                                               \
      ++check::failures;                                                         \
      fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);   \
    }                                                                            \
  } while (0)

#define CHECK_EQ(a, b)                                                           \
  do {                                                                           \
    ++check::checks;                                                             \
    const long long va_ = (long long)(a), vb_ = (long long)(b);                  \
    if (va_ != vb_) {                                                            \
      ++check::failures;                                                         \
      fprintf(stderr, "%s:%d: CHECK_EQ failed: %s == %s (%lld != %lld)\n",       \
              __FILE__, __LINE__, #a, #b, va_, vb_);                             \
    }                                                                            \
  } while (0)

#define CHECK_NEAR(a, b, tol)                                                    \
  do {                                                                           \
    ++check::checks;                                                             \
    const double va_ = (a), vb_ = (b);                                           \
    if (!(va_ - vb_ <= (tol) && vb_ - va_ <= (tol))) {                           \
      ++check::failures;                                                         \
      fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s ~ %s (%g vs %g, tol %g)\n",  \
              __FILE__, __LINE__, #a, #b, va_, vb_, (double)(tol));              \
    }                                                                            \
  } while (0)

#define TEST(name)                                                 \
  static void name();                                              \
  static check::Registration name##_registration(#name, name);     \
  static void name()

#endif
