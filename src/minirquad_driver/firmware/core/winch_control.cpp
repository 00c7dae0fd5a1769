#include "winch_control.h"

#include "messages.h"

namespace mrq {

WinchControl::WinchControl(const Config& config) : config_(config) { begin(0, 0); }

void WinchControl::begin(uint32_t now, int32_t encoder) {
  speed_ = 0;
  command_at_ = now;
  hold_ms_ = config_.winch_deadman_ms;
  integral_ = 0.0f;
  duty_ = 0;
  encoder0_ = encoder;
  window_n_ = 0;
  window_i_ = 0;
  position_ = 0;
  velocity_ = 0;
  tension_ = 0;
  tension_valid_ = false;
  sensor_reported_ = false;
  last_reading_at_ = now;
  over_count_ = 0;
  slow_since_ = now;
  slow_ = false;
  latch_ = 0;
  last_update_ = now;
  event_n_ = 0;
}

void WinchControl::raise(uint8_t code, uint32_t detail) {
  if (event_n_ == EVENTS) return;   // the queue is emptied every cycle: cannot happen
  events_[event_n_].code = code;
  events_[event_n_].detail = uint16_t(detail > 0xFFFF ? 0xFFFF : detail);
  ++event_n_;
}

bool WinchControl::pop_event(WinchEvent* event) {
  if (event_n_ == 0) return false;
  *event = events_[0];
  for (int i = 1; i < event_n_; ++i) events_[i - 1] = events_[i];
  --event_n_;
  return true;
}

bool WinchControl::command(int32_t speed, uint16_t hold_ms, uint32_t now) {
  command_at_ = now;
  hold_ms_ = config_.winch_deadman_ms;
  if (hold_ms && (hold_ms_ == 0 || hold_ms < hold_ms_)) hold_ms_ = hold_ms;
  if (speed <= 0) latch_ = 0;   // the host has stopped or pays out: it saw the error
  if (speed > 0 && (latch_ != 0 || !tension_valid_)) {
    brake();
    return false;
  }
  if ((speed > 0) != (speed_ > 0) || speed == 0) integral_ = 0.0f;
  speed_ = speed;
  return true;
}

void WinchControl::brake() {
  speed_ = 0;
  integral_ = 0.0f;
  duty_ = 0;
}

void WinchControl::update(uint32_t now, int32_t encoder, bool fresh, int32_t load_raw) {
  const uint32_t dt_ms = now - last_update_;
  last_update_ = now;

  // Spool position and speed (difference over the last WINDOW - 1 cycles: one encoder
  // count is 26 um, so a single 10 ms cycle would resolve only 2.6 mm/s).
  position_ = int32_t(float(encoder - encoder0_) * config_.winch_um_per_count);
  window_[window_i_] = encoder;
  window_t_[window_i_] = now;
  const int oldest = window_n_ < WINDOW ? 0 : (window_i_ + 1) % WINDOW;
  if (window_n_ < WINDOW) ++window_n_;
  const uint32_t span = now - window_t_[oldest];
  velocity_ = span ? int32_t(float(encoder - window_[oldest]) * config_.winch_um_per_count *
                             1000.0f / float(span))
                   : 0;
  window_i_ = (window_i_ + 1) % WINDOW;

  // Tension from the load cell; silence means the tension is unknown.
  if (fresh) {
    tension_ = int32_t(float(load_raw - config_.load_cell_tare) * config_.load_cell_mn_per_count);
    tension_valid_ = true;
    sensor_reported_ = false;
    last_reading_at_ = now;
    over_count_ = tension_ > config_.overtension_mn ? uint8_t(over_count_ + 1) : 0;
  } else if (now - last_reading_at_ > config_.load_cell_timeout_ms) {
    tension_valid_ = false;
    if (speed_ > 0) brake();
    if (!sensor_reported_) {
      sensor_reported_ = true;
      raise(ERR_WINCH_SENSOR, now - last_reading_at_);
    }
  }

  // Deadman: the speed must be refreshed by its commander, not by the link alone, and runs no
  // longer than the command allowed (the evidence it rests on ages on the MCU's clock too).
  if (hold_ms_ && speed_ != 0 && now - command_at_ > hold_ms_) {
    raise(ERR_WINCH_DEADMAN, now - command_at_);
    brake();
  }

  if (over_count_ >= config_.overtension_samples && latch_ != LATCH_OVERTENSION) {
    latch_ = LATCH_OVERTENSION;
    over_count_ = 0;
    if (speed_ > 0) brake();
    raise(ERR_WINCH_OVERTENSION, uint32_t(tension_));
  }

  // Stall: full drive, hardly turning, for stall_ms.
  const bool slow = speed_ > 0 && duty_ >= int16_t(config_.stall_duty) &&
                    velocity_ < config_.stall_speed;
  if (slow && !slow_) slow_since_ = now;
  slow_ = slow;
  if (slow && now - slow_since_ >= config_.stall_ms) {
    latch_ = LATCH_STALL;
    slow_ = false;
    brake();
    raise(ERR_WINCH_STALL, uint32_t(tension_ < 0 ? 0 : tension_));
  }

  // Speed loop.
  if (speed_ == 0) {
    duty_ = 0;
    return;
  }
  const float error = float(speed_ - velocity_);
  integral_ += config_.winch_ki * error * float(dt_ms) * 1e-3f;
  if (integral_ > 1.0f) integral_ = 1.0f;
  if (integral_ < -1.0f) integral_ = -1.0f;
  float d = float(speed_) / config_.winch_full_speed + config_.winch_kp * error + integral_;
  if (d > 1.0f) d = 1.0f;
  if (d < -1.0f) d = -1.0f;
  duty_ = int16_t(d * 1000.0f);
  if (duty_ == 0) duty_ = speed_ > 0 ? 1 : -1;   // zero means brake
}

}  // namespace mrq
