// The MiniRQuad firmware core: the protocol endpoint around the leg, winch and power
// controllers, behind the HAL. One instance per boot; no heap, no exceptions.
//
//   Firmware fw(hal, config);
//   fw.begin(cause);              // RESET_NOTICE first, INA219 set up, legs hold
//   for (;;) fw.loop();           // serial always; a control cycle every control_period_ms
//
// Per control cycle, in this order: read servos, IMU, winch sensors; host watchdog; winch
// rules (deadman, over-tension, stall, sensor loss); burrow sequencing; leg and winch
// outputs; then TELEMETRY and POWER when due. Commands are acked with their seq; a repeated
// (seq, type) is re-acked with its first result and not executed again.
#ifndef MRQ_FIRMWARE_H
#define MRQ_FIRMWARE_H

#include <stdint.h>

#include "cadence.h"
#include "config.h"
#include "frame.h"
#include "hal.h"
#include "legs.h"
#include "messages.h"
#include "power_monitor.h"
#include "winch_control.h"

namespace mrq {

class Firmware {
 public:
  Firmware(const Hal& hal, const Config& config);
  void begin(uint8_t reset_cause);
  void loop();
  // Clock value (ms) at which loop() next has work besides serial input.
  uint32_t next_due() const { return next_control_; }

  // State for tests and for the simulated plant.
  uint8_t mode() const { return mode_; }                // motion mode (IDLE .. ANCHORED)
  uint8_t reported_mode() const;                        // what telemetry says
  uint16_t flags() const;
  uint8_t burrow_mode() const { return burrow_; }       // BurrowMode of the running sequence
  bool unburrowing() const { return unburrowing_; }
  bool estopped() const { return estop_; }
  bool watchdog_tripped() const { return watchdog_; }
  const int32_t* goals() const { return goal_; }
  const WinchControl& winch() const { return winch_; }
  const DecoderStats& rx_stats() const { return decoder_.stats(); }
  uint32_t wrong_direction() const { return wrong_direction_; }
  uint32_t tx_dropped() const { return tx_dropped_; }
  uint8_t next_seq() const { return seq_; }
  uint32_t servo_read_errors() const { return servo_errors_; }

 private:
  void poll_serial(uint32_t now);
  void on_frame(const Frame& frame, uint32_t now);
  uint8_t execute(const Message& msg, uint32_t now);
  void control_cycle(uint32_t now);
  void read_sensors();
  void sequence_burrow(uint32_t now);
  void stop_motion();
  void send_telemetry(uint32_t now);
  void send(const Message& msg, uint32_t t_ms);
  void send_ack(uint8_t seq, uint8_t type, uint8_t result, uint32_t now);
  void send_error(uint8_t code, uint16_t detail, uint32_t now);
  void send_about(uint8_t type, uint32_t now);

  Hal hal_;
  const Config& config_;
  FrameDecoder decoder_;
  LegController legs_;
  WinchControl winch_;
  PowerMonitor power_;
  Cadence telemetry_;
  Cadence power_rate_;

  uint8_t seq_;
  uint8_t reset_cause_;
  uint8_t mode_;
  bool estop_;
  bool watchdog_;
  bool watchdog_reported_;
  uint8_t burrow_;
  bool unburrowing_;
  bool reached_;
  uint32_t reached_at_;
  uint32_t last_host_frame_;
  // The last command executed on each channel and its answer. A host retry is a byte copy
  // of its first frame, so the same (seq, type, t_ms) on its channel is a retry; a new
  // command 256 frames later with the same seq differs in the host's millisecond stamp.
  struct LastCommand {
    bool have;
    uint8_t seq;
    uint8_t type;
    uint32_t t_ms;
    uint8_t result;
  };
  LastCommand last_[CHANNEL_COUNT];
  uint32_t next_control_;
  uint32_t crc_reported_;
  uint32_t crc_reported_at_;

  ServoState servo_[4];
  bool servo_ok_;
  float angle_[4];
  int32_t goal_[4];
  int32_t pitch_;
  int16_t pitch_rate_;
  bool imu_ok_;

  uint32_t wrong_direction_;
  uint32_t tx_dropped_;
  uint32_t servo_errors_;
  uint8_t tx_[MAX_WIRE];
  Frame rx_frame_;
};

}  // namespace mrq

#endif
