// Leg control in SI: servo counts -> leg angles, desired motion -> goal velocities.
//
// The XL330s run in velocity mode (as in MiniRHex); the loop closed here is
//   goal rate = feed-forward rate + kp * (shortest-path angle error),
// clamped to a speed limit. Point-to-point moves (stand, set_legs, burrow poses) have no
// feed-forward; the Buehler clock gives both the angle and its rate. kp is in 1/s because
// the output is a rate set-point (MiniRHex's walk gain works out to about 3 1/s).
#ifndef MRQ_LEGS_H
#define MRQ_LEGS_H

#include <stdint.h>

#include "config.h"
#include "messages.h"

namespace mrq {

const float SERVO_RATE_LSB = 0.0239808f;   // rad/s per Present/Goal Velocity unit (0.229 rpm)
const int32_t SERVO_COUNTS = 4096;         // Present Position per turn

// Servo position -> leg angle in counts from the leg's zero, in (-2048, 2048].
int32_t leg_counts(const LegMount& mount, int32_t position);
float leg_angle(const LegMount& mount, int32_t position);          // rad, (-pi, pi]
int32_t leg_angle_urad(const LegMount& mount, int32_t position);   // wire units
float leg_rate(const LegMount& mount, int32_t velocity);           // rad/s
// Leg rate -> Goal Velocity, rounded and clamped to +-limit.
int32_t goal_velocity(const LegMount& mount, float rate, int32_t limit);

class LegController {
 public:
  explicit LegController(const Config& config);
  void hold(const float angle[4]);                                  // stop where they are
  void move(uint8_t mask, const float target[4], float speed, const float angle[4]);
  void clock(const SetGait& gait, uint32_t now);
  // All legs in a point-to-point move are within reach_tolerance of their targets.
  bool arrived(const float angle[4]) const;
  void rates(uint32_t now, const float angle[4], float rate[4]) const;

 private:
  enum Kind { POINT, CLOCK };
  const Config& config_;
  Kind kind_;
  float target_[4];
  float speed_;
  SetGait gait_;
  uint32_t gait_start_;
};

}  // namespace mrq

#endif
