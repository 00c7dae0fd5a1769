#include "gait_clock.h"

namespace mrq {

float wrap_angle(float a) {
  while (a > PI_F) a -= TWO_PI_F;
  while (a <= -PI_F) a += TWO_PI_F;
  return a;
}

LegSetpoint buehler_clock(const SetGait& g, int leg, uint32_t t_ms) {
  const uint32_t period = g.period_ms;                   // 50 .. 65535
  const uint32_t in_cycle = t_ms % period;               // < 65535: the shift cannot overflow
  const uint32_t frac = (in_cycle << 16) / period;       // 1/65536 of a cycle
  const uint32_t tau_q = (frac + g.phase[leg]) & 0xFFFFu;
  const float tau = float(tau_q) * (1.0f / 65536.0f);
  const float duty = float(g.duty) * 1e-4f;
  const float sweep = float(g.sweep) * 1e-6f;
  const float down = float(g.down) * 1e-6f;
  const float period_s = float(period) * 1e-3f;
  const float start = down - 0.5f * sweep;
  LegSetpoint sp;
  if (tau < duty) {
    sp.angle = start + sweep * tau / duty;
    sp.rate = sweep / (duty * period_s);
  } else {
    sp.angle = start + sweep + (TWO_PI_F - sweep) * (tau - duty) / (1.0f - duty);
    sp.rate = (TWO_PI_F - sweep) / ((1.0f - duty) * period_s);
  }
  // The arcs above rise (MiniRHex's own sign); forward in the protocol's sign is their
  // mirror about down: the stance sweeps the toe back, from down + sweep/2 to down - sweep/2.
  if (g.direction > 0) {
    sp.angle = 2.0f * down - sp.angle;
    sp.rate = -sp.rate;
  }
  sp.angle = wrap_angle(sp.angle);
  return sp;
}

}  // namespace mrq
