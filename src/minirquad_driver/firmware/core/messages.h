// The MiniRQuad serial protocol's messages (src/minirquad_driver/PROTOCOL.md), version 1.
// Payloads are fixed little-endian structs of wire integers; this header is the C++ twin of
// minirquad_driver/protocol/messages.py, and tests/golden_frames.txt keeps the two equal.
#ifndef MRQ_MESSAGES_H
#define MRQ_MESSAGES_H

#include <stddef.h>
#include <stdint.h>

namespace mrq {

const uint8_t PROTOCOL_VERSION = 2;
const int LEG_COUNT = 4;               // proximal-left, proximal-right, distal-left, distal-right
const int32_t PI_URAD = 3141593;       // angles on the wire: 1 urad, within (-pi, pi]
const int32_t TWO_PI_URAD = 6283185;
const size_t LOG_MAX = 200;

enum MsgType {
  MSG_TELEMETRY = 0x01, MSG_POWER = 0x02, MSG_ACK = 0x03, MSG_RESET_NOTICE = 0x04,
  MSG_ERROR = 0x05, MSG_LOG = 0x06, MSG_INFO = 0x07,
  MSG_HEARTBEAT = 0x10, MSG_SET_LEGS = 0x11, MSG_SET_GAIT = 0x12, MSG_BURROW = 0x13,
  MSG_WINCH = 0x14, MSG_ESTOP = 0x15, MSG_GET_INFO = 0x16
};

enum Mode {
  MODE_IDLE = 0, MODE_WALKING = 1, MODE_BURROW_RETRACT = 2, MODE_BURROW_FINAL = 3,
  MODE_ANCHORED = 4, MODE_ESTOPPED = 5, MODE_WATCHDOG = 6
};

enum Flag {
  FLAG_ESTOP = 0x01, FLAG_WATCHDOG_TRIPPED = 0x02, FLAG_WINCH_STALLED = 0x04,
  FLAG_ANCHOR_SLIPPING = 0x08, FLAG_VELOCITY_SATURATED = 0x10, FLAG_SLED_MOVING = 0x20,
  FLAG_TENSION_INVALID = 0x40
};
const uint16_t ALL_FLAGS = 0x7F;

enum BurrowMode { BURROW_UNBURROW = 0, BURROW_DH = 1, BURROW_DL = 2, BURROW_SH = 3 };
enum GaitKind { GAIT_STAND = 0, GAIT_CLOCK = 1 };
enum AckResult {
  ACK_OK = 0, ACK_INVALID = 1, ACK_ESTOPPED = 2, ACK_UNSUPPORTED = 3, ACK_BUSY = 4
};
enum ResetCause {
  RESET_POWER_ON = 0, RESET_WATCHDOG = 1, RESET_BROWNOUT = 2, RESET_SOFTWARE = 3,
  RESET_UNKNOWN = 255
};
enum ErrorCode {
  ERR_HOST_WATCHDOG = 1, ERR_RX_CRC = 2, ERR_WINCH_STALL = 3, ERR_SERVO_OVERLOAD = 4,
  ERR_ANCHOR_SLIP = 5, ERR_WINCH_DEADMAN = 6, ERR_WINCH_OVERTENSION = 7, ERR_WINCH_SENSOR = 8
};

// ---------------------------------------------------------------- MCU -> host
struct Telemetry {            // '<4i4hihiiiBH', 45 bytes
  int32_t leg_angle[4];       // urad, (-pi, pi]
  int16_t leg_velocity[4];    // mrad/s
  int32_t pitch;              // urad, nose up
  int16_t pitch_rate;         // mrad/s
  int32_t tension;            // mN
  int32_t spool_position;     // um reeled in since boot
  int32_t spool_velocity;     // um/s, reel-in positive
  uint8_t mode;               // Mode
  uint16_t flags;             // Flag bits
};
struct Power {                // '<HhhHH': raw INA219 registers
  uint16_t bus;
  int16_t shunt;
  int16_t current;
  uint16_t power;
  uint16_t cal;               // as read back; 0 = the chip reset
};
struct Ack {                  // '<BBB'
  uint8_t acked_seq;
  uint8_t acked_type;         // 0x10..0x16
  uint8_t result;             // AckResult
};
struct About {                // '<BHBHH', 8 bytes: RESET_NOTICE and INFO
  uint8_t protocol_version;
  uint16_t firmware_version;
  uint8_t reset_cause;        // ResetCause
  uint16_t telemetry_hz;
  uint16_t power_hz;
};
struct ErrorMsg {             // '<BH'
  uint8_t code;               // ErrorCode
  uint16_t detail;
};
struct Log {                  // UTF-8 text, at most 200 bytes
  uint8_t len;
  uint8_t text[LOG_MAX];
};

// ---------------------------------------------------------------- host -> MCU
struct SetLegs {              // '<B4i'
  uint8_t mask;               // bit i = leg i
  int32_t target[4];          // urad
};
struct SetGait {              // '<BHHii4Hb'
  uint8_t kind;               // GaitKind
  uint16_t period_ms;         // >= 50
  uint16_t duty;              // 1e-4, 1..9999
  int32_t sweep;              // urad, 1..2 pi
  int32_t down;               // urad
  uint16_t phase[4];          // 1/65536 cycle
  int8_t direction;           // +1 / -1
};
struct Burrow { uint8_t mode; };        // BurrowMode
struct Winch {                          // um/s reel-in, |v| <= 1 m/s; 0 brakes; hold_ms:
  int32_t speed;                        // how long the speed may run after receipt (its
  uint16_t hold_ms;                     // evidence's remaining age), 0 = the deadman alone
};
struct EStop { uint8_t engage; };       // 0 / 1

struct Message {
  uint8_t type;               // MsgType
  union {
    Telemetry telemetry;
    Power power;
    Ack ack;
    About about;              // RESET_NOTICE, INFO
    ErrorMsg error;
    Log log;
    SetLegs set_legs;
    SetGait set_gait;
    Burrow burrow;
    Winch winch;
    EStop estop;
  };
};

enum PayloadStatus {
  PAYLOAD_OK = 0,
  PAYLOAD_BAD = 1,    // wrong size or a value out of its range (counted as payload_errors)
  PAYLOAD_RANGE = 2   // an enum/flag value this version does not define (range_errors)
};

bool is_known_type(uint8_t type);
bool is_host_type(uint8_t type);

// What a host command sets: a newer command of the same channel replaces what an older one
// set (the legs follow the last of SET_LEGS, SET_GAIT, BURROW). The host resends only the
// newest command of a channel, so a retry is always recognised by that channel's last frame.
enum Channel { CHANNEL_LEGS = 0, CHANNEL_WINCH = 1, CHANNEL_ESTOP = 2, CHANNEL_INFO = 3,
               CHANNEL_COUNT = 4 };
// Channel of a host command type other than HEARTBEAT (which sets nothing).
Channel command_channel(uint8_t type);

// Payload bytes -> message. The same checks, in the same order, as messages.py's unpack.
PayloadStatus unpack_payload(uint8_t type, const uint8_t* payload, size_t n, Message* out);

// Message -> payload bytes. Returns the payload length, or -1 for a message the receiver
// would reject (checked by decoding what was written) or that does not fit in cap.
int pack_payload(const Message& msg, uint8_t* out, size_t cap);

}  // namespace mrq

#endif
