#include "config.h"

namespace mrq {

Config default_config() {
  Config c;
  c.firmware_version = 200;
  c.telemetry_hz = 100;
  c.power_hz = 50;
  c.control_period_ms = 10;     // one cycle per 100 Hz telemetry sample
  c.host_watchdog_ms = 500;
  c.winch_deadman_ms = 80;

  // Zero offsets as a zero-finder sketch would measure them; right legs mirrored.
  const LegMount legs[4] = {{1024, 1}, {3000, -1}, {2148, 1}, {500, -1}};
  for (int i = 0; i < 4; ++i) c.legs[i] = legs[i];
  c.servo_velocity_limit = 1620;   // XL330-M077 default Velocity Limit: 371 rpm
  c.walk_speed = 8.0f;
  c.burrow_speed = 1.0f;
  c.kp_move = 20.0f;
  c.kp_clock = 10.0f;
  c.reach_tolerance = 0.0087266f;  // 0.5 deg
  c.settle_ms = 500;

  // Pololu micro gearmotor 100:1 with a 12 CPR encoder: 1200 counts per spool turn; 5 mm
  // spool radius: 2 pi 5000 um / 1200.
  c.winch_um_per_count = 26.17994f;
  c.winch_full_speed = 80000.0f;
  c.winch_kp = 1.0e-5f;
  c.winch_ki = 2.0e-4f;
  // 1 kg load cell, 1 mV/V at 5 V excitation, HX711 gain 128 (+-20 mV = +-2^23): about
  // 2.14e5 counts per N; the tare is what a slack rope reads.
  c.load_cell_tare = 8400;
  c.load_cell_mn_per_count = 0.0046762f;
  c.load_cell_timeout_ms = 50;     // four missed readings at 80 SPS
  c.overtension_mn = 12000;
  c.overtension_samples = 3;
  c.stall_speed = 2000;
  c.stall_duty = 950;
  c.stall_ms = 200;

  c.ina219_address = 0x40;
  c.ina219_config = 0x39E7;
  c.ina219_cal = 4096;
  return c;
}

}  // namespace mrq
