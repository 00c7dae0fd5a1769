// The software-in-the-loop link between the simulated plant (Python, minirquad_sim) and the
// firmware core (this process), one exchange per firmware loop() over a SOCK_SEQPACKET
// socketpair. Fixed little-endian structs, then a variable tail of serial bytes; the Python
// twin is minirquad_sim/firmware_link.py. A magic, version or size mismatch aborts.
//
// The plant is the master clock (as ArduPilot's and PX4's SITL): each PlantFrame carries the
// simulated time, and the firmware's millis() is derived from it and nothing else.
#ifndef MRQ_SITL_LINK_H
#define MRQ_SITL_LINK_H

#include <stdint.h>

namespace sitl {

const uint32_t PLANT_MAGIC = 0x5153524Du;   // "MRSQ"
const uint32_t FW_MAGIC = 0x4651524Du;      // "MRQF"
const uint32_t HELLO_MAGIC = 0x4851524Du;   // "MRQH"
const uint16_t VERSION = 1;
const uint16_t MAX_SERIAL = 4096;           // serial bytes per exchange, each way

enum Command { CMD_RUN = 0, CMD_RESET = 1 };

#pragma pack(push, 1)

// Sent once by the firmware at start: the calibration it was built with, which the plant
// checks against the robot it simulates.
struct Hello {
  uint32_t magic;
  uint16_t version;
  uint16_t size;
  int32_t leg_zero[4];
  int8_t leg_sign[4];
  float winch_um_per_count;
  int32_t load_cell_tare;
  float load_cell_mn_per_count;
  uint16_t ina219_cal;
  uint16_t control_period_ms;
};

struct PlantFrame {
  uint32_t magic;
  uint16_t version;
  uint16_t size;           // sizeof(PlantFrame): the serial bytes follow
  uint32_t frame;
  uint64_t sim_us;         // simulated time since the plant started
  uint8_t command;         // Command
  uint8_t reset_cause;     // with CMD_RESET: ResetCause for the RESET_NOTICE
  uint8_t servo_ok;        // bit i: servo i answered the sync read
  uint8_t imu_ok;
  int32_t servo_position[4];   // Present Position, 1/4096 rev, multi-turn
  int32_t servo_velocity[4];   // Present Velocity, 0.229 rpm
  int16_t servo_current[4];    // mA
  uint16_t servo_voltage[4];   // 0.1 V
  uint16_t ina219[6];          // registers 0x00..0x05 as the chip holds them
  uint8_t ina219_ok;
  uint8_t load_cell_seq;       // +1 for every completed HX711 conversion
  int32_t load_cell_raw;       // the latest conversion
  int32_t winch_encoder;       // counts, reel-in positive
  int32_t pitch;               // urad, nose up
  int16_t pitch_rate;          // mrad/s
  uint16_t rx_len;             // host -> MCU bytes that arrived since the last exchange
};

struct FwFrame {
  uint32_t magic;
  uint16_t version;
  uint16_t size;           // sizeof(FwFrame): the serial bytes follow
  uint32_t frame;          // echo of the PlantFrame's
  uint32_t fw_ms;          // the firmware clock at this exchange
  uint32_t next_due_ms;    // when loop() next has work besides serial input
  int32_t goal_velocity[4];    // 0.229 rpm (the last written)
  int16_t winch_duty;          // permille, + reels in
  uint8_t winch_brake;
  uint8_t watchdog_kicked;
  uint8_t ina219_writes;       // how many of the pairs below are valid
  uint8_t ina219_reg[4];
  uint16_t ina219_value[4];
  // What the firmware is doing (a hint for the plant's kinematic body model only).
  uint8_t motion_mode;         // Mode: IDLE .. ANCHORED
  uint8_t burrow_mode;         // BurrowMode of the running sequence
  uint8_t unburrowing;
  uint8_t next_seq;            // the seq of the next frame the firmware sends
  uint32_t rx_frames;          // decoder statistics of the host -> MCU stream
  uint32_t rx_rejected;
  uint32_t rx_crc_errors;
  uint32_t tx_dropped;
  uint16_t tx_len;             // MCU -> host bytes written during this exchange
};

#pragma pack(pop)

static_assert(sizeof(Hello) == 44, "Hello layout");
static_assert(sizeof(PlantFrame) == 102, "PlantFrame layout");
static_assert(sizeof(FwFrame) == 75, "FwFrame layout");

}  // namespace sitl

#endif
