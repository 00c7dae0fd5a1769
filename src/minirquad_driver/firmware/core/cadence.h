// A fixed-rate schedule on the millisecond clock: hz ticks per second on average (the
// remainder of 1000 / hz is carried), restarted rather than replayed after a long stall.
#ifndef MRQ_CADENCE_H
#define MRQ_CADENCE_H

#include <stdint.h>

namespace mrq {

class Cadence {
 public:
  Cadence() : hz_(0), next_(0), rem_(0) {}
  void start(uint32_t now, uint16_t hz) {
    hz_ = hz;
    next_ = now;
    rem_ = 0;
  }
  uint32_t next() const { return next_; }
  bool enabled() const { return hz_ != 0; }
  // True (and the schedule advanced) when a tick is due at `now`.
  bool due(uint32_t now) {
    if (hz_ == 0 || int32_t(now - next_) < 0) return false;
    const uint32_t total = 1000u + rem_;
    next_ += total / hz_;
    rem_ = uint16_t(total % hz_);
    const uint32_t period = 1000u / hz_;
    if (int32_t(now - next_) > int32_t(2 * period)) {   // fell behind: restart, no burst
      next_ = now + period;
      rem_ = 0;
    }
    return true;
  }

 private:
  uint16_t hz_;
  uint32_t next_;
  uint16_t rem_;
};

}  // namespace mrq

#endif
