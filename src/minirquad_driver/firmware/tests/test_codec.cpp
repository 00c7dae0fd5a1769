// The C++ codec against the golden frames the Python codec wrote (golden_frames.txt), plus
// CRC and COBS reference vectors.
#include <stdio.h>
#include <string.h>

#include <string>
#include <vector>

#include "../core/cobs.h"
#include "../core/crc16.h"
#include "../core/frame.h"
#include "check.h"

extern const char* g_golden_path;

namespace {

using mrq::Message;
typedef std::vector<long long> Fields;

std::vector<uint8_t> unhex(const std::string& s) {
  std::vector<uint8_t> out;
  if (s == "-") return out;
  for (size_t i = 0; i + 1 < s.size(); i += 2) {
    out.push_back(uint8_t(strtoul(s.substr(i, 2).c_str(), 0, 16)));
  }
  return out;
}

// Wire integers (struct order) -> message, written member by member: independent of the
// codec's own unpack.
Message fill(uint8_t type, const Fields& f) {
  Message m;
  memset(&m, 0, sizeof(m));
  m.type = type;
  size_t k = 0;
  switch (type) {
    case mrq::MSG_TELEMETRY: {
      mrq::Telemetry& t = m.telemetry;
      for (int i = 0; i < 4; ++i) t.leg_angle[i] = int32_t(f[k++]);
      for (int i = 0; i < 4; ++i) t.leg_velocity[i] = int16_t(f[k++]);
      t.pitch = int32_t(f[k++]);
      t.pitch_rate = int16_t(f[k++]);
      t.tension = int32_t(f[k++]);
      t.spool_position = int32_t(f[k++]);
      t.spool_velocity = int32_t(f[k++]);
      t.mode = uint8_t(f[k++]);
      t.flags = uint16_t(f[k++]);
      break;
    }
    case mrq::MSG_POWER:
      m.power.bus = uint16_t(f[0]);
      m.power.shunt = int16_t(f[1]);
      m.power.current = int16_t(f[2]);
      m.power.power = uint16_t(f[3]);
      m.power.cal = uint16_t(f[4]);
      break;
    case mrq::MSG_ACK:
      m.ack.acked_seq = uint8_t(f[0]);
      m.ack.acked_type = uint8_t(f[1]);
      m.ack.result = uint8_t(f[2]);
      break;
    case mrq::MSG_RESET_NOTICE:
    case mrq::MSG_INFO:
      m.about.protocol_version = uint8_t(f[0]);
      m.about.firmware_version = uint16_t(f[1]);
      m.about.reset_cause = uint8_t(f[2]);
      m.about.telemetry_hz = uint16_t(f[3]);
      m.about.power_hz = uint16_t(f[4]);
      break;
    case mrq::MSG_ERROR:
      m.error.code = uint8_t(f[0]);
      m.error.detail = uint16_t(f[1]);
      break;
    case mrq::MSG_LOG:
      m.log.len = uint8_t(f.size());
      for (size_t i = 0; i < f.size() && i < mrq::LOG_MAX; ++i) m.log.text[i] = uint8_t(f[i]);
      break;
    case mrq::MSG_SET_LEGS:
      m.set_legs.mask = uint8_t(f[0]);
      for (int i = 0; i < 4; ++i) m.set_legs.target[i] = int32_t(f[1 + i]);
      break;
    case mrq::MSG_SET_GAIT: {
      mrq::SetGait& g = m.set_gait;
      g.kind = uint8_t(f[0]);
      g.period_ms = uint16_t(f[1]);
      g.duty = uint16_t(f[2]);
      g.sweep = int32_t(f[3]);
      g.down = int32_t(f[4]);
      for (int i = 0; i < 4; ++i) g.phase[i] = uint16_t(f[5 + i]);
      g.direction = int8_t(f[9]);
      break;
    }
    case mrq::MSG_BURROW: m.burrow.mode = uint8_t(f[0]); break;
    case mrq::MSG_WINCH:
      m.winch.speed = int32_t(f[0]);
      m.winch.hold_ms = uint16_t(f[1]);
      break;
    case mrq::MSG_ESTOP: m.estop.engage = uint8_t(f[0]); break;
    default: break;
  }
  return m;
}

// Message -> wire integers (the inverse of fill).
Fields fields_of(const Message& m) {
  Fields f;
  switch (m.type) {
    case mrq::MSG_TELEMETRY: {
      const mrq::Telemetry& t = m.telemetry;
      for (int i = 0; i < 4; ++i) f.push_back(t.leg_angle[i]);
      for (int i = 0; i < 4; ++i) f.push_back(t.leg_velocity[i]);
      f.push_back(t.pitch);
      f.push_back(t.pitch_rate);
      f.push_back(t.tension);
      f.push_back(t.spool_position);
      f.push_back(t.spool_velocity);
      f.push_back(t.mode);
      f.push_back(t.flags);
      break;
    }
    case mrq::MSG_POWER: {
      const mrq::Power& p = m.power;
      long long v[] = {p.bus, p.shunt, p.current, p.power, p.cal};
      f.assign(v, v + 5);
      break;
    }
    case mrq::MSG_ACK: {
      long long v[] = {m.ack.acked_seq, m.ack.acked_type, m.ack.result};
      f.assign(v, v + 3);
      break;
    }
    case mrq::MSG_RESET_NOTICE:
    case mrq::MSG_INFO: {
      const mrq::About& a = m.about;
      long long v[] = {a.protocol_version, a.firmware_version, a.reset_cause, a.telemetry_hz,
                       a.power_hz};
      f.assign(v, v + 5);
      break;
    }
    case mrq::MSG_ERROR:
      f.push_back(m.error.code);
      f.push_back(m.error.detail);
      break;
    case mrq::MSG_LOG:
      for (int i = 0; i < m.log.len; ++i) f.push_back(m.log.text[i]);
      break;
    case mrq::MSG_SET_LEGS:
      f.push_back(m.set_legs.mask);
      for (int i = 0; i < 4; ++i) f.push_back(m.set_legs.target[i]);
      break;
    case mrq::MSG_SET_GAIT: {
      const mrq::SetGait& g = m.set_gait;
      long long v[] = {g.kind, g.period_ms, g.duty, g.sweep, g.down, g.phase[0], g.phase[1],
                       g.phase[2], g.phase[3], g.direction};
      f.assign(v, v + 10);
      break;
    }
    case mrq::MSG_BURROW: f.push_back(m.burrow.mode); break;
    case mrq::MSG_WINCH:
      f.push_back(m.winch.speed);
      f.push_back(m.winch.hold_ms);
      break;
    case mrq::MSG_ESTOP: f.push_back(m.estop.engage); break;
    default: break;
  }
  return f;
}

const uint32_t* counter_array(const mrq::DecoderStats& s, uint32_t out[9]) {
  const uint32_t v[9] = {s.frames, s.cobs_errors, s.crc_errors, s.short_frames,
                         s.version_errors, s.unknown_types, s.payload_errors, s.range_errors,
                         s.overflows};
  memcpy(out, v, sizeof(v));
  return out;
}

struct GoldenCounts {
  int ok, payload, range, streams, refused;
};

GoldenCounts run_golden() {
  GoldenCounts n = {0, 0, 0, 0, 0};
  FILE* fp = fopen(g_golden_path, "r");
  CHECK(fp != 0);
  if (!fp) return n;
  static char line[8192];
  while (fgets(line, sizeof(line), fp)) {
    if (line[0] == '#' || line[0] == '\n') continue;
    std::vector<std::string> tok;
    for (char* t = strtok(line, " \n"); t; t = strtok(0, " \n")) tok.push_back(t);
    if (tok[0] == "frame") {
      const std::string name = tok[1], expect = tok[2];
      const uint8_t type = uint8_t(atoi(tok[3].c_str()));
      const uint8_t seq = uint8_t(atoi(tok[4].c_str()));
      const uint32_t t_ms = uint32_t(strtoul(tok[5].c_str(), 0, 10));
      const int nf = atoi(tok[6].c_str());
      Fields fields;
      for (int i = 0; i < nf; ++i) fields.push_back(atoll(tok[7 + i].c_str()));
      const size_t rest = 7 + size_t(nf < 0 ? 0 : nf);
      const std::vector<uint8_t> payload = unhex(tok[rest]);
      const std::vector<uint8_t> wire = unhex(tok[rest + 1]);
      mrq::FrameDecoder dec;
      mrq::Frame frame;
      int got = 0;
      for (size_t i = 0; i < wire.size(); ++i) got += dec.push(wire[i], &frame) ? 1 : 0;
      if (expect == "ok") {
        ++n.ok;
        CHECK_EQ(got, 1);
        if (got != 1) {
          fprintf(stderr, "  golden %s: not decoded\n", name.c_str());
          continue;
        }
        CHECK_EQ(frame.seq, seq);
        CHECK_EQ(frame.t_ms, t_ms);
        CHECK_EQ(frame.message.type, type);
        CHECK(fields_of(frame.message) == fields);
        // Fields -> bytes: byte for byte the Python codec's frame.
        uint8_t out[mrq::MAX_WIRE];
        const size_t len = mrq::encode_frame(fill(type, fields), seq, t_ms, out, sizeof(out));
        const bool same = len == wire.size() && memcmp(out, &wire[0], len) == 0;
        CHECK(same);
        if (!same) fprintf(stderr, "  golden %s: encoded bytes differ\n", name.c_str());
      } else {
        const mrq::DecoderStats& s = dec.stats();
        CHECK_EQ(got, 0);
        if (expect == "payload") {
          ++n.payload;
          CHECK_EQ(s.payload_errors, 1);
        } else {
          ++n.range;
          CHECK_EQ(s.range_errors, 1);
        }
        uint32_t c[9];
        counter_array(s, c);
        uint32_t total = 0;
        for (int i = 1; i < 9; ++i) total += c[i];
        CHECK_EQ(total, 1);
        if (got != 0 || total != 1) fprintf(stderr, "  golden %s: not rejected\n", name.c_str());
        if (nf >= 0) {   // the encoder refuses what the decoder rejects
          uint8_t buf[mrq::MAX_FRAME];
          const bool refused = mrq::pack_payload(fill(type, fields), buf, sizeof(buf)) < 0;
          CHECK(refused);
          n.refused += refused ? 1 : 0;
        }
        (void)payload;
      }
    } else if (tok[0] == "stream") {
      ++n.streams;
      const std::vector<uint8_t> wire = unhex(tok[2]);
      mrq::FrameDecoder dec;
      mrq::Frame frame;
      for (size_t i = 0; i < wire.size(); ++i) dec.push(wire[i], &frame);
      uint32_t c[9];
      counter_array(dec.stats(), c);
      bool same = true;
      for (int i = 0; i < 9; ++i) same = same && c[i] == uint32_t(atol(tok[3 + i].c_str()));
      CHECK(same);
      if (!same) fprintf(stderr, "  golden stream %s: counters differ\n", tok[1].c_str());
      CHECK_EQ(dec.stats().bytes_in, wire.size());
    }
  }
  fclose(fp);
  return n;
}

}  // namespace

TEST(golden_frames_byte_for_byte) {
  const GoldenCounts n = run_golden();
  printf("golden: %d ok frames, %d payload errors, %d range errors (%d refused by the "
         "encoder), %d streams\n", n.ok, n.payload, n.range, n.refused, n.streams);
  CHECK(n.ok > 80);
  CHECK(n.payload > 40);
  CHECK(n.range > 15);
  CHECK(n.streams >= 20);
}

TEST(crc_check_value) {
  const uint8_t s[] = "123456789";
  CHECK_EQ(mrq::crc16_ccitt_false(s, 9), 0x29B1);
  CHECK_EQ(mrq::crc16_ccitt_false(s, 0), 0xFFFF);
}

TEST(cobs_reference_vectors) {
  // Cheshire and Baker's examples (as listed on Wikipedia), without the delimiter.
  struct V {
    std::vector<uint8_t> raw, enc;
  };
  std::vector<V> v;
  const uint8_t a[] = {0x00}, ae[] = {0x01, 0x01};
  const uint8_t b[] = {0x00, 0x00}, be[] = {0x01, 0x01, 0x01};
  const uint8_t c[] = {0x00, 0x11, 0x00}, ce[] = {0x01, 0x02, 0x11, 0x01};
  const uint8_t d[] = {0x11, 0x22, 0x00, 0x33}, de[] = {0x03, 0x11, 0x22, 0x02, 0x33};
  const uint8_t e[] = {0x11, 0x00, 0x00, 0x00}, ee[] = {0x02, 0x11, 0x01, 0x01, 0x01};
  v.push_back(V{std::vector<uint8_t>(a, a + 1), std::vector<uint8_t>(ae, ae + 2)});
  v.push_back(V{std::vector<uint8_t>(b, b + 2), std::vector<uint8_t>(be, be + 3)});
  v.push_back(V{std::vector<uint8_t>(c, c + 3), std::vector<uint8_t>(ce, ce + 4)});
  v.push_back(V{std::vector<uint8_t>(d, d + 4), std::vector<uint8_t>(de, de + 5)});
  v.push_back(V{std::vector<uint8_t>(e, e + 4), std::vector<uint8_t>(ee, ee + 5)});
  V full;   // 01..FE: one full block, no trailing empty block
  full.enc.push_back(0xFF);
  for (int i = 1; i <= 0xFE; ++i) {
    full.raw.push_back(uint8_t(i));
    full.enc.push_back(uint8_t(i));
  }
  v.push_back(full);
  V over = full;   // 01..FE FF
  over.raw.push_back(0xFF);
  over.enc.push_back(0x02);
  over.enc.push_back(0xFF);
  v.push_back(over);
  V empty;
  empty.enc.push_back(0x01);
  v.push_back(empty);
  for (size_t i = 0; i < v.size(); ++i) {
    uint8_t out[600];
    const size_t n = mrq::cobs_encode(v[i].raw.empty() ? out : &v[i].raw[0], v[i].raw.size(),
                                      out, sizeof(out));
    CHECK(n == v[i].enc.size() && memcmp(out, &v[i].enc[0], n) == 0);
    size_t m = 0;
    uint8_t back[600];
    CHECK(mrq::cobs_decode(&v[i].enc[0], v[i].enc.size(), back, sizeof(back), &m));
    CHECK(m == v[i].raw.size() && (m == 0 || memcmp(back, &v[i].raw[0], m) == 0));
  }
  uint8_t tiny[4];
  const uint8_t five[] = {1, 2, 3, 4, 5};
  CHECK_EQ(mrq::cobs_encode(five, 5, tiny, sizeof(tiny)), 0);   // no room: refused
}
