#include "firmware.h"

#include <string.h>

#include "burrow.h"
#include "gait_clock.h"

namespace mrq {

namespace {

const uint32_t RX_CRC_REPORT_MS = 1000;   // at most one ERROR RX_CRC per second

int16_t saturate16(float v, bool* saturated) {
  if (v > 32767.0f) {
    *saturated = true;
    return 32767;
  }
  if (v < -32767.0f) {
    *saturated = true;
    return -32767;
  }
  return int16_t(v + (v >= 0.0f ? 0.5f : -0.5f));
}

}  // namespace

Firmware::Firmware(const Hal& hal, const Config& config)
    : hal_(hal), config_(config), legs_(config), winch_(config), power_(config), seq_(0),
      reset_cause_(RESET_UNKNOWN), mode_(MODE_IDLE), estop_(false), watchdog_(false),
      watchdog_reported_(false), burrow_(BURROW_UNBURROW), unburrowing_(false),
      reached_(false), reached_at_(0), last_host_frame_(0), next_control_(0), crc_reported_(0),
      crc_reported_at_(0), servo_ok_(false), pitch_(0), pitch_rate_(0), imu_ok_(false),
      wrong_direction_(0), tx_dropped_(0), servo_errors_(0) {
  memset(servo_, 0, sizeof(servo_));
  memset(last_, 0, sizeof(last_));
  for (int i = 0; i < 4; ++i) {
    angle_[i] = 0.0f;
    goal_[i] = 0;
  }
}

void Firmware::begin(uint8_t reset_cause) {
  reset_cause_ = reset_cause;
  const uint32_t now = hal_.clock->millis();
  send_about(MSG_RESET_NOTICE, now);   // before anything else: the host restarts baselines
  power_.begin(*hal_.i2c);
  read_sensors();
  legs_.hold(angle_);                  // the legs stay where they are
  winch_.begin(now, hal_.winch->encoder());
  last_host_frame_ = now;
  crc_reported_at_ = now;
  next_control_ = now;
  telemetry_.start(now, config_.telemetry_hz);
  power_rate_.start(now, config_.power_hz);
}

void Firmware::loop() {
  hal_.watchdog->kick();
  const uint32_t now = hal_.clock->millis();
  poll_serial(now);
  if (int32_t(now - next_control_) >= 0) {
    control_cycle(now);
    next_control_ += config_.control_period_ms;
    if (int32_t(now - next_control_) >= 0) next_control_ = now + config_.control_period_ms;
  }
}

uint8_t Firmware::reported_mode() const {
  if (estop_) return MODE_ESTOPPED;
  if (watchdog_) return MODE_WATCHDOG;
  return mode_;
}

uint16_t Firmware::flags() const {
  uint16_t f = 0;
  if (estop_) f |= FLAG_ESTOP;
  if (watchdog_) f |= FLAG_WATCHDOG_TRIPPED;
  if (winch_.stalled()) f |= FLAG_WINCH_STALLED;
  if (!winch_.tension_valid()) f |= FLAG_TENSION_INVALID;
  return f;
}

// ------------------------------------------------------------------ host -> MCU

void Firmware::poll_serial(uint32_t now) {
  for (;;) {
    const int c = hal_.serial->read();
    if (c < 0) break;
    if (decoder_.push(uint8_t(c), &rx_frame_)) on_frame(rx_frame_, now);
  }
}

void Firmware::on_frame(const Frame& frame, uint32_t now) {
  last_host_frame_ = now;   // any valid frame proves the link
  const uint8_t type = frame.message.type;
  if (!is_host_type(type)) {
    ++wrong_direction_;     // an MCU -> host type has no ack the host could accept
    return;
  }
  if (type == MSG_HEARTBEAT) {
    if (watchdog_) {
      watchdog_ = false;
      watchdog_reported_ = false;
    }
    send_ack(frame.seq, type, ACK_OK, now);
    return;
  }
  LastCommand& last = last_[command_channel(type)];
  if (last.have && frame.seq == last.seq && type == last.type && frame.t_ms == last.t_ms) {
    send_ack(frame.seq, type, last.result, now);   // a retry: answer, do not execute again
    if (type == MSG_GET_INFO) send_about(MSG_INFO, now);
    return;
  }
  const uint8_t result = execute(frame.message, now);
  if (result == ACK_OK && watchdog_ && type != MSG_ESTOP && type != MSG_GET_INFO) {
    watchdog_ = false;
    watchdog_reported_ = false;
  }
  last.have = true;
  last.seq = frame.seq;
  last.type = type;
  last.t_ms = frame.t_ms;
  last.result = result;
  send_ack(frame.seq, type, result, now);
  if (type == MSG_GET_INFO) send_about(MSG_INFO, now);
}

uint8_t Firmware::execute(const Message& msg, uint32_t now) {
  if (msg.type == MSG_GET_INFO) return ACK_OK;
  if (msg.type == MSG_ESTOP) {
    estop_ = msg.estop.engage != 0;
    if (estop_) stop_motion();
    return ACK_OK;
  }
  if (estop_) return ACK_ESTOPPED;   // legs hold, winch brakes until released
  switch (msg.type) {
    case MSG_SET_LEGS: {
      float target[4];
      for (int i = 0; i < 4; ++i) target[i] = float(msg.set_legs.target[i]) * 1e-6f;
      legs_.move(msg.set_legs.mask, target, config_.walk_speed, angle_);
      mode_ = MODE_IDLE;
      burrow_ = BURROW_UNBURROW;
      unburrowing_ = false;
      return ACK_OK;
    }
    case MSG_SET_GAIT: {
      const SetGait& g = msg.set_gait;
      if (g.kind == GAIT_STAND) {
        const float down = float(g.down) * 1e-6f;
        const float target[4] = {down, down, down, down};
        legs_.move(0x0F, target, config_.walk_speed, angle_);
        mode_ = MODE_IDLE;
      } else {
        legs_.clock(g, now);
        mode_ = MODE_WALKING;
      }
      burrow_ = BURROW_UNBURROW;
      unburrowing_ = false;
      return ACK_OK;
    }
    case MSG_BURROW: {
      const BurrowPoses* poses = burrow_poses(msg.burrow.mode);
      float target[4] = {0.0f, 0.0f, 0.0f, 0.0f};
      if (poses) pose_targets(poses->retract, target);
      legs_.move(0x0F, target, config_.burrow_speed, angle_);
      burrow_ = msg.burrow.mode;
      unburrowing_ = poses == 0;
      mode_ = poses ? MODE_BURROW_RETRACT : MODE_IDLE;
      reached_ = false;
      return ACK_OK;
    }
    case MSG_WINCH:
      return winch_.command(msg.winch.speed, msg.winch.hold_ms, now) ? ACK_OK : ACK_BUSY;
    default:
      return ACK_UNSUPPORTED;
  }
}

void Firmware::stop_motion() {
  if (mode_ == MODE_WALKING || mode_ == MODE_BURROW_RETRACT || mode_ == MODE_BURROW_FINAL) {
    mode_ = MODE_IDLE;
  }
  burrow_ = BURROW_UNBURROW;
  unburrowing_ = false;
  legs_.hold(angle_);
  winch_.brake();
}

// ------------------------------------------------------------------ control cycle

void Firmware::read_sensors() {
  servo_ok_ = hal_.servos->read(servo_);
  if (servo_ok_) {
    for (int i = 0; i < 4; ++i) angle_[i] = leg_angle(config_.legs[i], servo_[i].position);
  } else {
    ++servo_errors_;
  }
  imu_ok_ = hal_.imu->read(&pitch_, &pitch_rate_);
}

void Firmware::control_cycle(uint32_t now) {
  read_sensors();
  int32_t load = 0;
  const bool fresh = hal_.winch->load_cell(&load);

  // Safety first: the host watchdog, then the winch's own rules.
  if (!watchdog_ && now - last_host_frame_ > config_.host_watchdog_ms) {
    watchdog_ = true;
    stop_motion();
  }
  if (estop_ || watchdog_) winch_.brake();
  winch_.update(now, hal_.winch->encoder(), fresh, load);
  WinchEvent event;
  while (winch_.pop_event(&event)) send_error(event.code, event.detail, now);
  if (watchdog_ && !watchdog_reported_) {
    watchdog_reported_ = true;
    send_error(ERR_HOST_WATCHDOG, 0, now);
  }
  const uint32_t crc_errors = decoder_.stats().crc_errors;
  if (crc_errors != crc_reported_ && now - crc_reported_at_ >= RX_CRC_REPORT_MS) {
    crc_reported_ = crc_errors;
    crc_reported_at_ = now;
    send_error(ERR_RX_CRC, uint16_t(crc_errors > 0xFFFF ? 0xFFFF : crc_errors), now);
  }

  sequence_burrow(now);
  if (servo_ok_) {   // stale angles steer nothing: on a failed read no goal is written,
    float rate[4];   // and the servos' bus watchdog stops them if it keeps failing
    legs_.rates(now, angle_, rate);
    for (int i = 0; i < 4; ++i) {
      goal_[i] = goal_velocity(config_.legs[i], rate[i], config_.servo_velocity_limit);
    }
    hal_.servos->write_goal_velocity(goal_);
  }
  hal_.winch->drive(winch_.duty(), winch_.braking());

  if (telemetry_.due(now)) send_telemetry(now);
  if (power_rate_.due(now)) {
    Message msg;
    msg.type = MSG_POWER;
    if (power_.sample(*hal_.i2c, &msg.power)) send(msg, now);
  }
}

void Firmware::sequence_burrow(uint32_t now) {
  const bool arrived = servo_ok_ && legs_.arrived(angle_);
  if (mode_ == MODE_BURROW_RETRACT && arrived) {
    if (!reached_) {
      reached_ = true;
      reached_at_ = now;
    }
    if (now - reached_at_ >= config_.settle_ms) {
      float target[4];
      pose_targets(burrow_poses(burrow_)->final_, target);
      legs_.move(0x0F, target, config_.burrow_speed, angle_);
      mode_ = MODE_BURROW_FINAL;
    }
  } else if (mode_ == MODE_BURROW_FINAL && arrived) {
    mode_ = MODE_ANCHORED;
  }
  if (unburrowing_ && arrived) unburrowing_ = false;
}

// ------------------------------------------------------------------ MCU -> host

void Firmware::send_telemetry(uint32_t now) {
  // Stale angles or an unknown pitch are not sent as if they were measured: the host
  // then sees the stream stop and marks its outputs stale.
  if (!servo_ok_ || !imu_ok_) return;
  Message msg;
  msg.type = MSG_TELEMETRY;
  Telemetry& t = msg.telemetry;
  bool saturated = false;
  for (int i = 0; i < 4; ++i) {
    t.leg_angle[i] = leg_angle_urad(config_.legs[i], servo_[i].position);
    t.leg_velocity[i] =
        saturate16(leg_rate(config_.legs[i], servo_[i].velocity) * 1000.0f, &saturated);
  }
  t.pitch = pitch_;
  t.pitch_rate = pitch_rate_;
  t.tension = winch_.tension();
  t.spool_position = winch_.position();
  t.spool_velocity = winch_.velocity();
  t.mode = reported_mode();
  t.flags = uint16_t(flags() | (saturated ? FLAG_VELOCITY_SATURATED : 0));
  send(msg, now);
}

void Firmware::send(const Message& msg, uint32_t t_ms) {
  const size_t n = encode_frame(msg, seq_, t_ms, tx_, sizeof(tx_));
  seq_ = uint8_t(seq_ + 1);   // also for a frame that is dropped: the host counts the gap
  if (n == 0 || hal_.serial->writable() < n) {
    ++tx_dropped_;
    return;
  }
  hal_.serial->write(tx_, n);
}

void Firmware::send_ack(uint8_t seq, uint8_t type, uint8_t result, uint32_t now) {
  Message msg;
  msg.type = MSG_ACK;
  msg.ack.acked_seq = seq;
  msg.ack.acked_type = type;
  msg.ack.result = result;
  send(msg, now);
}

void Firmware::send_error(uint8_t code, uint16_t detail, uint32_t now) {
  Message msg;
  msg.type = MSG_ERROR;
  msg.error.code = code;
  msg.error.detail = detail;
  send(msg, now);
}

void Firmware::send_about(uint8_t type, uint32_t now) {
  Message msg;
  msg.type = type;
  msg.about.protocol_version = PROTOCOL_VERSION;
  msg.about.firmware_version = config_.firmware_version;
  msg.about.reset_cause = reset_cause_;
  msg.about.telemetry_hz = config_.telemetry_hz;
  msg.about.power_hz = config_.power_hz;
  send(msg, now);
}

}  // namespace mrq
