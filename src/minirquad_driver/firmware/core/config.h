// Robot constants the firmware is built with. default_config() describes the simulated
// robot (the SITL plant checks it at start-up); a real robot overrides the measured values
// (leg zeros, load-cell calibration) in its sketch.
#ifndef MRQ_CONFIG_H
#define MRQ_CONFIG_H

#include <stdint.h>

namespace mrq {

// How a leg's servo is mounted: Present Position at leg angle 0 (leg pointing along -z_B),
// and +1 if a positive servo turn moves the leg forward (left side), -1 if mirrored (right).
struct LegMount {
  int32_t zero;
  int8_t sign;
};

struct Config {
  uint16_t firmware_version;
  uint16_t telemetry_hz;          // TELEMETRY stream rate (sampled at control cycles)
  uint16_t power_hz;              // POWER stream rate; 0 = off
  uint16_t control_period_ms;     // one servo read/compute/write cycle
  uint16_t host_watchdog_ms;      // no valid host frame for this long: motors stop
  uint16_t winch_deadman_ms;      // a moving winch needs a WINCH command this often; 0 = off

  LegMount legs[4];
  int32_t servo_velocity_limit;   // |Goal Velocity| cap, 0.229 rpm (XL330 Velocity Limit)
  float walk_speed;               // rad/s: leg speed limit for gaits, stand and set_legs
  float burrow_speed;             // rad/s: leg speed limit while burrowing in sand
  float kp_move;                  // 1/s: position gain of point-to-point moves
  float kp_clock;                 // 1/s: position gain around the Buehler clock
  float reach_tolerance;          // rad: a leg within this of its target has arrived
  uint16_t settle_ms;             // held at the retracting pose before the final move

  float winch_um_per_count;       // rope per encoder count at the spool
  float winch_full_speed;         // um/s at full duty without load (feed-forward)
  float winch_kp;                 // duty per um/s of speed error
  float winch_ki;                 // duty per um of accumulated speed error
  int32_t load_cell_tare;         // HX711 raw with a slack rope
  float load_cell_mn_per_count;   // mN per HX711 count
  uint16_t load_cell_timeout_ms;  // no reading for this long: the tension is unknown
  int32_t overtension_mn;         // rope/anchor limit
  uint8_t overtension_samples;    // consecutive readings above it before the winch brakes
  int32_t stall_speed;            // um/s: slower than this under full drive is a stall
  uint16_t stall_duty;            // permille: "full drive"
  uint16_t stall_ms;              // for this long

  uint8_t ina219_address;
  uint16_t ina219_config;         // 32 V, /8 gain, bus 12-bit, shunt 12-bit x16, continuous
  uint16_t ina219_cal;            // 4096: 0.1 mA and 2 mW per bit with a 0.1 ohm shunt
};

Config default_config();

}  // namespace mrq

#endif
