// The Buehler clock (MiniRHex): a leg's desired angle is piecewise linear in time. Per cycle
// the leg sweeps the slow "stance" arc of width sweep centred on down during duty * period,
// then recovers through the remaining 2 pi - sweep. Angles are the protocol's (positive toe
// forward, away from p): walking forward (direction +1) the toe sweeps backward under the hip
// in stance, so the angle falls, and the leg turns on the same way through its recovery. Time stays an integer (ms) and the phase
// a 16-bit fraction, so nothing drifts however long the gait runs; floats only for the arcs.
#ifndef MRQ_GAIT_CLOCK_H
#define MRQ_GAIT_CLOCK_H

#include <stdint.h>

#include "messages.h"

namespace mrq {

struct LegSetpoint {
  float angle;   // rad, wrapped to (-pi, pi]
  float rate;    // rad/s
};

// Desired angle and rate of leg `leg` at t_ms since the gait started (any uint32 value).
LegSetpoint buehler_clock(const SetGait& gait, int leg, uint32_t t_ms);

const float PI_F = 3.14159265f;
const float TWO_PI_F = 6.28318531f;

// Wrap to (-pi, pi].
float wrap_angle(float a);

}  // namespace mrq

#endif
