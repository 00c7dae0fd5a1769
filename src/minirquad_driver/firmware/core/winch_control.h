// Winch speed control and the winch's safety rules, checked every control cycle before
// the output is computed:
//   deadman       a non-zero speed needs a WINCH command every winch_deadman_ms, or sooner
//                 when the command set a shorter hold (the age its evidence had left);
//   over-tension  overtension_samples readings above overtension_mn brake and latch;
//   stall         full drive but slower than stall_speed for stall_ms brakes and latches;
//   sensor loss   no load-cell reading for load_cell_timeout_ms: tension unknown, no reel-in.
// A latch refuses reel-in until the host commands zero or pay-out (it has seen the error).
// E-stop and the host watchdog call brake(). The speed loop is feed-forward plus PI on the
// encoder speed; the output is a signed PWM duty in permille.
#ifndef MRQ_WINCH_CONTROL_H
#define MRQ_WINCH_CONTROL_H

#include <stdint.h>

#include "config.h"

namespace mrq {

struct WinchEvent {   // an ERROR to report (code 0: none)
  uint8_t code;
  uint16_t detail;
};

class WinchControl {
 public:
  explicit WinchControl(const Config& config);
  void begin(uint32_t now, int32_t encoder);
  // A WINCH command (um/s; hold_ms: how long it may run after now, 0 = the deadman alone).
  // Returns false if refused: reel-in while latched or the tension is unknown (the speed is
  // then left at zero).
  bool command(int32_t speed, uint16_t hold_ms, uint32_t now);
  void brake();                                         // speed to zero, now
  // One control cycle; errors it raises are queued for pop_event.
  void update(uint32_t now, int32_t encoder, bool fresh, int32_t load_raw);
  bool pop_event(WinchEvent* event);

  int16_t duty() const { return duty_; }                // permille, + reels in
  bool braking() const { return duty_ == 0; }
  int32_t speed_command() const { return speed_; }
  int32_t tension() const { return tension_; }          // mN, last reading
  bool tension_valid() const { return tension_valid_; }
  int32_t position() const { return position_; }        // um reeled in since boot
  int32_t velocity() const { return velocity_; }        // um/s, reel-in positive
  bool stalled() const { return latch_ == LATCH_STALL; }

 private:
  enum { LATCH_NONE = 0, LATCH_STALL = 1, LATCH_OVERTENSION = 2 };
  static const int WINDOW = 6;     // encoder samples for the speed: 50 ms at 10 ms cycles
  static const int EVENTS = 4;

  void raise(uint8_t code, uint32_t detail);

  const Config& config_;
  int32_t speed_;
  uint32_t command_at_;
  uint32_t hold_ms_;       // the last command's own limit, never above the deadman
  float integral_;
  int16_t duty_;
  int32_t encoder0_;
  int32_t window_[WINDOW];
  uint32_t window_t_[WINDOW];
  int window_n_;
  int window_i_;
  int32_t position_;
  int32_t velocity_;
  int32_t tension_;
  bool tension_valid_;
  bool sensor_reported_;
  uint32_t last_reading_at_;
  uint8_t over_count_;
  uint32_t slow_since_;
  bool slow_;
  uint8_t latch_;
  uint32_t last_update_;
  WinchEvent events_[EVENTS];
  int event_n_;
};

}  // namespace mrq

#endif
