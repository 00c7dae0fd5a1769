#include "messages.h"

#include <string.h>

#include "wire.h"

namespace mrq {

namespace {

// Cursor over a payload: reads fixed-width little-endian fields in struct order.
class Reader {
 public:
  Reader(const uint8_t* p) : p_(p) {}
  uint8_t u8() { return *p_++; }
  int8_t i8() { return int8_t(*p_++); }
  uint16_t u16() { uint16_t v = get_u16(p_); p_ += 2; return v; }
  int16_t i16() { int16_t v = get_i16(p_); p_ += 2; return v; }
  int32_t i32() { int32_t v = get_i32(p_); p_ += 4; return v; }

 private:
  const uint8_t* p_;
};

class Writer {
 public:
  Writer(uint8_t* p) : p_(p), n_(0) {}
  void u8(uint8_t v) { p_[n_++] = v; }
  void u16(uint16_t v) { put_u16(p_ + n_, v); n_ += 2; }
  void i16(int16_t v) { u16(uint16_t(v)); }
  void i32(int32_t v) { put_u32(p_ + n_, uint32_t(v)); n_ += 4; }
  int size() const { return int(n_); }

 private:
  uint8_t* p_;
  size_t n_;
};

bool angle_ok(int32_t a) { return a >= -PI_URAD && a <= PI_URAD; }

// Payload size of each fixed-size type; -1 for LOG (variable), -2 for unknown types.
int payload_size(uint8_t type) {
  switch (type) {
    case MSG_TELEMETRY: return 45;
    case MSG_POWER: return 10;
    case MSG_ACK: return 3;
    case MSG_RESET_NOTICE:
    case MSG_INFO: return 8;
    case MSG_ERROR: return 3;
    case MSG_LOG: return -1;
    case MSG_HEARTBEAT:
    case MSG_GET_INFO: return 0;
    case MSG_SET_LEGS: return 17;
    case MSG_SET_GAIT: return 22;
    case MSG_BURROW: return 1;
    case MSG_WINCH: return 6;
    case MSG_ESTOP: return 1;
    default: return -2;
  }
}

bool reset_cause_ok(uint8_t c) { return c <= RESET_SOFTWARE || c == RESET_UNKNOWN; }

}  // namespace

bool is_known_type(uint8_t type) { return payload_size(type) != -2; }
bool is_host_type(uint8_t type) { return type >= MSG_HEARTBEAT && type <= MSG_GET_INFO; }

Channel command_channel(uint8_t type) {
  switch (type) {
    case MSG_WINCH: return CHANNEL_WINCH;
    case MSG_ESTOP: return CHANNEL_ESTOP;
    case MSG_GET_INFO: return CHANNEL_INFO;
    default: return CHANNEL_LEGS;   // SET_LEGS, SET_GAIT, BURROW
  }
}

PayloadStatus unpack_payload(uint8_t type, const uint8_t* payload, size_t n, Message* out) {
  const int size = payload_size(type);
  if (size == -2) return PAYLOAD_BAD;
  if (size >= 0 && n != size_t(size)) return PAYLOAD_BAD;
  out->type = type;
  Reader r(payload);
  switch (type) {
    case MSG_TELEMETRY: {
      Telemetry& t = out->telemetry;
      for (int i = 0; i < 4; ++i) t.leg_angle[i] = r.i32();
      for (int i = 0; i < 4; ++i) t.leg_velocity[i] = r.i16();
      t.pitch = r.i32();
      t.pitch_rate = r.i16();
      t.tension = r.i32();
      t.spool_position = r.i32();
      t.spool_velocity = r.i32();
      t.mode = r.u8();
      t.flags = r.u16();
      for (int i = 0; i < 4; ++i) {
        if (!angle_ok(t.leg_angle[i])) return PAYLOAD_BAD;
      }
      if (!angle_ok(t.pitch)) return PAYLOAD_BAD;
      if (t.mode > MODE_WATCHDOG) return PAYLOAD_RANGE;
      if (t.flags & ~ALL_FLAGS) return PAYLOAD_RANGE;
      return PAYLOAD_OK;
    }
    case MSG_POWER: {
      Power& p = out->power;
      p.bus = r.u16();
      p.shunt = r.i16();
      p.current = r.i16();
      p.power = r.u16();
      p.cal = r.u16();
      return PAYLOAD_OK;
    }
    case MSG_ACK: {
      Ack& a = out->ack;
      a.acked_seq = r.u8();
      a.acked_type = r.u8();
      a.result = r.u8();
      if (!is_host_type(a.acked_type)) return PAYLOAD_RANGE;
      if (a.result > ACK_BUSY) return PAYLOAD_RANGE;
      return PAYLOAD_OK;
    }
    case MSG_RESET_NOTICE:
    case MSG_INFO: {
      About& a = out->about;
      a.protocol_version = r.u8();
      a.firmware_version = r.u16();
      a.reset_cause = r.u8();
      a.telemetry_hz = r.u16();
      a.power_hz = r.u16();
      if (a.protocol_version != PROTOCOL_VERSION) return PAYLOAD_RANGE;
      if (!reset_cause_ok(a.reset_cause)) return PAYLOAD_RANGE;
      return PAYLOAD_OK;
    }
    case MSG_ERROR: {
      ErrorMsg& e = out->error;
      e.code = r.u8();
      e.detail = r.u16();
      if (e.code < ERR_HOST_WATCHDOG || e.code > ERR_WINCH_SENSOR) return PAYLOAD_RANGE;
      return PAYLOAD_OK;
    }
    case MSG_LOG: {
      if (n > LOG_MAX) return PAYLOAD_BAD;
      out->log.len = uint8_t(n);
      if (n) memcpy(out->log.text, payload, n);
      return PAYLOAD_OK;
    }
    case MSG_HEARTBEAT:
    case MSG_GET_INFO:
      return PAYLOAD_OK;
    case MSG_SET_LEGS: {
      SetLegs& s = out->set_legs;
      s.mask = r.u8();
      for (int i = 0; i < 4; ++i) s.target[i] = r.i32();
      if (s.mask > 0x0F) return PAYLOAD_BAD;
      for (int i = 0; i < 4; ++i) {
        if (!angle_ok(s.target[i])) return PAYLOAD_BAD;
      }
      return PAYLOAD_OK;
    }
    case MSG_SET_GAIT: {
      SetGait& g = out->set_gait;
      g.kind = r.u8();
      g.period_ms = r.u16();
      g.duty = r.u16();
      g.sweep = r.i32();
      g.down = r.i32();
      for (int i = 0; i < 4; ++i) g.phase[i] = r.u16();
      g.direction = r.i8();
      if (g.kind > GAIT_CLOCK || g.period_ms < 50 || g.duty < 1 || g.duty > 9999 ||
          g.sweep < 1 || g.sweep > TWO_PI_URAD - 1 || !angle_ok(g.down) ||
          (g.direction != 1 && g.direction != -1)) {
        return PAYLOAD_BAD;
      }
      return PAYLOAD_OK;
    }
    case MSG_BURROW:
      out->burrow.mode = r.u8();
      return out->burrow.mode <= BURROW_SH ? PAYLOAD_OK : PAYLOAD_BAD;
    case MSG_WINCH:
      out->winch.speed = r.i32();
      out->winch.hold_ms = r.u16();
      return (out->winch.speed >= -1000000 && out->winch.speed <= 1000000) ? PAYLOAD_OK
                                                                           : PAYLOAD_BAD;
    case MSG_ESTOP:
      out->estop.engage = r.u8();
      return out->estop.engage <= 1 ? PAYLOAD_OK : PAYLOAD_BAD;
    default:
      return PAYLOAD_BAD;
  }
}

int pack_payload(const Message& msg, uint8_t* out, size_t cap) {
  const int size = payload_size(msg.type);
  if (size == -2) return -1;
  if (size == -1) {   // LOG
    if (msg.log.len > LOG_MAX || msg.log.len > cap) return -1;
    memcpy(out, msg.log.text, msg.log.len);
    return msg.log.len;
  }
  if (size_t(size) > cap) return -1;
  Writer w(out);
  switch (msg.type) {
    case MSG_TELEMETRY: {
      const Telemetry& t = msg.telemetry;
      for (int i = 0; i < 4; ++i) w.i32(t.leg_angle[i]);
      for (int i = 0; i < 4; ++i) w.i16(t.leg_velocity[i]);
      w.i32(t.pitch);
      w.i16(t.pitch_rate);
      w.i32(t.tension);
      w.i32(t.spool_position);
      w.i32(t.spool_velocity);
      w.u8(t.mode);
      w.u16(t.flags);
      break;
    }
    case MSG_POWER: {
      const Power& p = msg.power;
      w.u16(p.bus);
      w.i16(p.shunt);
      w.i16(p.current);
      w.u16(p.power);
      w.u16(p.cal);
      break;
    }
    case MSG_ACK:
      w.u8(msg.ack.acked_seq);
      w.u8(msg.ack.acked_type);
      w.u8(msg.ack.result);
      break;
    case MSG_RESET_NOTICE:
    case MSG_INFO: {
      const About& a = msg.about;
      w.u8(a.protocol_version);
      w.u16(a.firmware_version);
      w.u8(a.reset_cause);
      w.u16(a.telemetry_hz);
      w.u16(a.power_hz);
      break;
    }
    case MSG_ERROR:
      w.u8(msg.error.code);
      w.u16(msg.error.detail);
      break;
    case MSG_HEARTBEAT:
    case MSG_GET_INFO:
      break;
    case MSG_SET_LEGS:
      w.u8(msg.set_legs.mask);
      for (int i = 0; i < 4; ++i) w.i32(msg.set_legs.target[i]);
      break;
    case MSG_SET_GAIT: {
      const SetGait& g = msg.set_gait;
      w.u8(g.kind);
      w.u16(g.period_ms);
      w.u16(g.duty);
      w.i32(g.sweep);
      w.i32(g.down);
      for (int i = 0; i < 4; ++i) w.u16(g.phase[i]);
      w.u8(uint8_t(g.direction));
      break;
    }
    case MSG_BURROW: w.u8(msg.burrow.mode); break;
    case MSG_WINCH: w.i32(msg.winch.speed); w.u16(msg.winch.hold_ms); break;
    case MSG_ESTOP: w.u8(msg.estop.engage); break;
    default: return -1;
  }
  // Never emit what a receiver would drop: the written bytes must decode cleanly.
  Message check;
  if (unpack_payload(msg.type, out, size_t(w.size()), &check) != PAYLOAD_OK) return -1;
  return w.size();
}

}  // namespace mrq
