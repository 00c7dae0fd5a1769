#include "legs.h"

#include "gait_clock.h"

namespace mrq {

namespace {

float clamp(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

}  // namespace

int32_t leg_counts(const LegMount& mount, int32_t position) {
  // Modulo one turn in unsigned arithmetic: a multi-turn position never overflows here.
  uint32_t c = (uint32_t(position) - uint32_t(mount.zero)) & uint32_t(SERVO_COUNTS - 1);
  if (mount.sign < 0) c = (uint32_t(SERVO_COUNTS) - c) & uint32_t(SERVO_COUNTS - 1);
  return c > uint32_t(SERVO_COUNTS / 2) ? int32_t(c) - SERVO_COUNTS : int32_t(c);
}

float leg_angle(const LegMount& mount, int32_t position) {
  return float(leg_counts(mount, position)) * (TWO_PI_F / float(SERVO_COUNTS));
}

int32_t leg_angle_urad(const LegMount& mount, int32_t position) {
  // 2 pi / 4096 rad = 1533.9808 urad; +-2048 counts -> +-3141593, inside the wire range.
  const float u = float(leg_counts(mount, position)) * 1533.98077f;
  return int32_t(u + (u >= 0.0f ? 0.5f : -0.5f));
}

float leg_rate(const LegMount& mount, int32_t velocity) {
  return float(mount.sign) * float(velocity) * SERVO_RATE_LSB;
}

int32_t goal_velocity(const LegMount& mount, float rate, int32_t limit) {
  const float raw = clamp(float(mount.sign) * rate / SERVO_RATE_LSB, -float(limit),
                          float(limit));
  return int32_t(raw + (raw >= 0.0f ? 0.5f : -0.5f));
}

LegController::LegController(const Config& config)
    : config_(config), kind_(POINT), speed_(config.walk_speed), gait_(), gait_start_(0) {
  for (int i = 0; i < 4; ++i) target_[i] = 0.0f;
}

void LegController::hold(const float angle[4]) {
  kind_ = POINT;
  speed_ = config_.walk_speed;
  for (int i = 0; i < 4; ++i) target_[i] = angle[i];
}

void LegController::move(uint8_t mask, const float target[4], float speed,
                         const float angle[4]) {
  if (kind_ == CLOCK) {   // legs left out of the mask stop where the clock had them
    for (int i = 0; i < 4; ++i) target_[i] = angle[i];
  }
  kind_ = POINT;
  speed_ = speed;
  for (int i = 0; i < 4; ++i) {
    if (mask & (1u << i)) target_[i] = wrap_angle(target[i]);
  }
}

void LegController::clock(const SetGait& gait, uint32_t now) {
  kind_ = CLOCK;
  speed_ = config_.walk_speed;
  gait_ = gait;
  gait_start_ = now;
}

bool LegController::arrived(const float angle[4]) const {
  if (kind_ != POINT) return false;
  for (int i = 0; i < 4; ++i) {
    const float e = wrap_angle(target_[i] - angle[i]);
    if (e > config_.reach_tolerance || e < -config_.reach_tolerance) return false;
  }
  return true;
}

void LegController::rates(uint32_t now, const float angle[4], float rate[4]) const {
  for (int i = 0; i < 4; ++i) {
    float want;
    if (kind_ == CLOCK) {
      const LegSetpoint sp = buehler_clock(gait_, i, now - gait_start_);
      want = sp.rate + config_.kp_clock * wrap_angle(sp.angle - angle[i]);
    } else {
      want = config_.kp_move * wrap_angle(target_[i] - angle[i]);
    }
    rate[i] = clamp(want, -speed_, speed_);
  }
}

}  // namespace mrq
