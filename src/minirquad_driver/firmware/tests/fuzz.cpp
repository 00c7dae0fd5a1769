// Fuzz test of the frame decoder and the command handler (no libFuzzer needed: a seeded
// generator of random and mutated streams). Run under AddressSanitizer and UBSan.
//
//   fuzz [--bytes N] [--seed S]        exit 0: no finding; prints what it fed and how long
//   fuzz --canary-asan | --canary-ubsan   a deliberate bug, to prove the sanitizers are on
//
// Part 1, decoder: streams of intact frames (every type, random fields), intact frames with
// undefined enum/flag values, random junk with and without zeros, frames with 1-3 flipped
// bits, truncated frames, and overlong runs. Checks: every intact frame comes out, in
// order, and nothing else; each non-empty segment lands in exactly one counter (segments
// counted independently here); overflows = segments longer than MAX_ENCODED; bytes_in.
// Part 2, command handler: the firmware on a fake board fed host commands (valid, mutated,
// junk) with the clock stepping across the uint32 wrap. Checks: every decoded host frame is
// answered by exactly one ACK, the firmware's own output decodes with no reject at all.
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <vector>

#include "../core/cobs.h"
#include "../core/crc16.h"
#include "../core/firmware.h"
#include "../core/frame.h"
#include "../core/wire.h"
#include "fake_hal.h"

namespace {

typedef std::vector<uint8_t> Bytes;

struct Rng {
  uint64_t s;
  explicit Rng(uint64_t seed) : s(seed * 2654435761u + 0x9E3779B97F4A7C15ull) {}
  uint64_t next() {   // xorshift64*
    s ^= s >> 12;
    s ^= s << 25;
    s ^= s >> 27;
    return s * 2685821657736338717ull;
  }
  uint32_t below(uint32_t n) { return uint32_t(next() % n); }
  int32_t range(int32_t lo, int32_t hi) { return lo + int32_t(next() % uint64_t(hi - lo + 1)); }
};

int failures = 0;
#define EXPECT(cond, ...)                                              \
  do {                                                                 \
    if (!(cond)) {                                                     \
      if (failures++ < 20) fprintf(stderr, "fuzz: " __VA_ARGS__);      \
    }                                                                  \
  } while (0)

const uint8_t TYPES[] = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07,
                         0x10, 0x11, 0x12, 0x13, 0x14, 0x15, 0x16};

mrq::Message random_message(Rng& r, uint8_t type) {
  mrq::Message m;
  memset(&m, 0, sizeof(m));
  m.type = type;
  switch (type) {
    case mrq::MSG_TELEMETRY: {
      mrq::Telemetry& t = m.telemetry;
      for (int i = 0; i < 4; ++i) t.leg_angle[i] = r.range(-mrq::PI_URAD, mrq::PI_URAD);
      for (int i = 0; i < 4; ++i) t.leg_velocity[i] = int16_t(r.next());
      t.pitch = r.range(-mrq::PI_URAD, mrq::PI_URAD);
      t.pitch_rate = int16_t(r.next());
      t.tension = int32_t(r.next());
      t.spool_position = int32_t(r.next());
      t.spool_velocity = int32_t(r.next());
      t.mode = uint8_t(r.below(7));
      t.flags = uint16_t(r.next() & mrq::ALL_FLAGS);
      break;
    }
    case mrq::MSG_POWER:
      m.power.bus = uint16_t(r.next());
      m.power.shunt = int16_t(r.next());
      m.power.current = int16_t(r.next());
      m.power.power = uint16_t(r.next());
      m.power.cal = uint16_t(r.next());
      break;
    case mrq::MSG_ACK:
      m.ack.acked_seq = uint8_t(r.next());
      m.ack.acked_type = uint8_t(0x10 + r.below(7));
      m.ack.result = uint8_t(r.below(5));
      break;
    case mrq::MSG_RESET_NOTICE:
    case mrq::MSG_INFO:
      m.about.protocol_version = mrq::PROTOCOL_VERSION;
      m.about.firmware_version = uint16_t(r.next());
      m.about.reset_cause = r.below(5) == 4 ? 255 : uint8_t(r.below(4));
      m.about.telemetry_hz = uint16_t(r.next());
      m.about.power_hz = uint16_t(r.next());
      break;
    case mrq::MSG_ERROR:
      m.error.code = uint8_t(1 + r.below(8));
      m.error.detail = uint16_t(r.next());
      break;
    case mrq::MSG_LOG:
      m.log.len = uint8_t(r.below(mrq::LOG_MAX + 1));
      for (int i = 0; i < m.log.len; ++i) m.log.text[i] = uint8_t(r.next());
      break;
    case mrq::MSG_SET_LEGS:
      m.set_legs.mask = uint8_t(r.below(16));
      for (int i = 0; i < 4; ++i) m.set_legs.target[i] = r.range(-mrq::PI_URAD, mrq::PI_URAD);
      break;
    case mrq::MSG_SET_GAIT: {
      mrq::SetGait& g = m.set_gait;
      g.kind = uint8_t(r.below(2));
      g.period_ms = uint16_t(r.range(50, 65535));
      g.duty = uint16_t(r.range(1, 9999));
      g.sweep = r.range(1, mrq::TWO_PI_URAD - 1);
      g.down = r.range(-mrq::PI_URAD, mrq::PI_URAD);
      for (int i = 0; i < 4; ++i) g.phase[i] = uint16_t(r.next());
      g.direction = r.below(2) ? 1 : -1;
      break;
    }
    case mrq::MSG_BURROW: m.burrow.mode = uint8_t(r.below(4)); break;
    case mrq::MSG_WINCH:
      m.winch.speed = r.range(-1000000, 1000000);
      m.winch.hold_ms = uint16_t(r.range(0, 65535));
      break;
    case mrq::MSG_ESTOP: m.estop.engage = uint8_t(r.below(2)); break;
    default: break;
  }
  return m;
}

Bytes encode(const mrq::Message& m, uint8_t seq, uint32_t t) {
  uint8_t buf[mrq::MAX_WIRE];
  const size_t n = mrq::encode_frame(m, seq, t, buf, sizeof(buf));
  return Bytes(buf, buf + n);
}

// A frame built from raw payload bytes, bypassing the encoder's checks.
Bytes raw_frame(uint8_t type, const uint8_t* payload, size_t n) {
  uint8_t body[mrq::MAX_FRAME];
  body[0] = mrq::PROTOCOL_VERSION;
  body[1] = type;
  body[2] = 0;
  mrq::put_u32(body + 3, 0);
  memcpy(body + 7, payload, n);
  mrq::put_u16(body + 7 + n, mrq::crc16_ccitt_false(body, 7 + n));
  uint8_t out[mrq::MAX_WIRE];
  out[0] = 0;
  const size_t e = mrq::cobs_encode(body, 9 + n, out + 1, sizeof(out) - 2);
  out[1 + e] = 0;
  return Bytes(out, out + e + 2);
}

// An intact frame with an enum/flag value this protocol version does not define.
Bytes bad_field_frame(Rng& r) {
  uint8_t p[45];
  memset(p, 0, sizeof(p));
  switch (r.below(5)) {
    case 0: p[42] = uint8_t(7 + r.below(249)); return raw_frame(0x01, p, 45);  // mode
    case 1: mrq::put_u16(p + 43, uint16_t(0x80 << r.below(9))); return raw_frame(0x01, p, 45);
    case 2: p[1] = uint8_t(0x17 + r.below(200)); return raw_frame(0x03, p, 3);   // acked type
    case 3: p[0] = mrq::PROTOCOL_VERSION + 1; return raw_frame(0x07, p, 8);      // version
    default: p[0] = uint8_t(9 + r.below(200)); return raw_frame(0x05, p, 3);    // error code
  }
}

void append(Bytes& a, const Bytes& b) { a.insert(a.end(), b.begin(), b.end()); }

// Non-empty segments between zeros, and how many of them are longer than MAX_ENCODED.
void count_segments(const Bytes& w, uint64_t* segments, uint64_t* overlong) {
  size_t run = 0;
  for (size_t i = 0; i <= w.size(); ++i) {
    if (i == w.size() || w[i] == 0) {
      if (run) ++*segments;
      if (run > mrq::MAX_ENCODED) ++*overlong;
      run = 0;
    } else {
      ++run;
    }
  }
}

uint64_t fuzz_decoder(Rng& r, uint64_t target, uint64_t* streams) {
  uint64_t total = 0;
  while (total < target) {
    Bytes wire;
    std::vector<Bytes> good;
    uint64_t bad_fields = 0;
    const int n = 1 + int(r.below(60));
    for (int k = 0; k < n; ++k) {
      const uint32_t kind = r.below(10);
      if (kind < 4) {
        const Bytes f = encode(random_message(r, TYPES[r.below(14)]), uint8_t(k), r.below(~0u));
        append(wire, f);
        good.push_back(f);
      } else if (kind == 4) {
        append(wire, bad_field_frame(r));
        ++bad_fields;
      } else if (kind == 5) {   // junk; sometimes no zero at all, sometimes overlong
        const size_t len = r.below(4) == 0 ? 200 + r.below(600) : 1 + r.below(60);
        const bool zeros = r.below(2) != 0;
        for (size_t i = 0; i < len; ++i) {
          uint8_t b = uint8_t(r.next());
          if (!zeros && b == 0) b = 0x5A;
          wire.push_back(b);
        }
      } else if (kind < 8) {    // 1-3 distinct flipped bits inside a frame (delimiters kept)
        Bytes f = encode(random_message(r, TYPES[r.below(14)]), uint8_t(k), 0);
        const uint32_t bits = uint32_t(f.size() - 2) * 8;
        uint32_t flipped[3];
        const int flips = 1 + int(r.below(3));
        for (int i = 0; i < flips; ++i) {
          uint32_t b;
          bool again;
          do {   // two flips of one bit would cancel out and leave an intact frame
            b = r.below(bits);
            again = false;
            for (int j = 0; j < i; ++j) again = again || flipped[j] == b;
          } while (again);
          flipped[i] = b;
          f[1 + b / 8] ^= uint8_t(1 << (b % 8));
        }
        append(wire, f);
      } else {                  // cut before its last byte: a frame lost to a reset
        const Bytes f = encode(random_message(r, TYPES[r.below(14)]), uint8_t(k), 0);
        wire.insert(wire.end(), f.begin(), f.begin() + 1 + r.below(uint32_t(f.size() - 2)));
      }
    }
    wire.push_back(0);
    mrq::FrameDecoder dec;
    mrq::Frame frame;
    std::vector<Bytes> got;
    for (size_t i = 0; i < wire.size(); ++i) {
      if (dec.push(wire[i], &frame)) got.push_back(encode(frame.message, frame.seq, frame.t_ms));
    }
    // Intact frames come out in order; nothing that was not sent intact comes out (random
    // junk passing COBS, CRC, version, type, size and range checks: odds below 1e-7).
    size_t j = 0;
    for (size_t i = 0; i < got.size() && j < good.size(); ++i) {
      if (got[i] == good[j]) ++j;
    }
    EXPECT(j == good.size(), "intact frame lost (%zu of %zu)\n", j, good.size());
    EXPECT(got.size() == good.size(), "%zu frames decoded, %zu sent intact\n", got.size(),
           good.size());
    const mrq::DecoderStats& s = dec.stats();
    uint64_t segments = 0, overlong = 0;
    count_segments(wire, &segments, &overlong);
    const uint64_t counted = uint64_t(s.frames) + s.cobs_errors + s.crc_errors + s.short_frames +
                             s.version_errors + s.unknown_types + s.payload_errors +
                             s.range_errors + s.overflows;
    EXPECT(counted == segments, "segments %llu, counted %llu\n", (unsigned long long)segments,
           (unsigned long long)counted);
    EXPECT(s.overflows == overlong, "overflows %u, overlong %llu\n", s.overflows,
           (unsigned long long)overlong);
    EXPECT(s.frames == got.size(), "frames counter\n");
    EXPECT(s.bytes_in == wire.size(), "bytes_in\n");
    EXPECT(s.range_errors >= bad_fields, "range errors %u < %llu\n", s.range_errors,
           (unsigned long long)bad_fields);
    total += wire.size();
    ++*streams;
  }
  return total;
}

uint64_t fuzz_handler(Rng& r, uint64_t target, uint64_t* acks_out) {
  uint64_t total = 0;
  while (total < target) {
    fake::Board board;
    const mrq::Config config = mrq::default_config();
    mrq::Firmware fw(board.hal(), config);
    board.clock.ms = r.below(2) ? 0xFFFFFFFFu - r.below(3000) : r.below(100000);
    fw.begin(uint8_t(r.below(4)));
    board.winch.load = 8400 + int32_t(r.below(3000000));
    for (int step = 0; step < 400; ++step) {
      const uint32_t kind = r.below(8);
      Bytes chunk;
      if (kind < 4) {
        mrq::Message m = random_message(r, uint8_t(0x10 + r.below(7)));
        chunk = encode(m, uint8_t(r.below(8)), board.clock.ms);   // small seqs: retries
      } else if (kind < 6) {
        chunk = encode(random_message(r, uint8_t(0x10 + r.below(7))), uint8_t(r.next()), 0);
        const int flips = 1 + int(r.below(4));
        for (int i = 0; i < flips; ++i) chunk[r.below(uint32_t(chunk.size()))] ^= uint8_t(1 << r.below(8));
      } else if (kind == 6) {
        chunk.resize(1 + r.below(80));
        for (size_t i = 0; i < chunk.size(); ++i) chunk[i] = uint8_t(r.next());
      } else {
        chunk = encode(random_message(r, TYPES[r.below(7)]), 0, 0);   // wrong direction
      }
      board.serial.feed(chunk);
      total += chunk.size();
      board.clock.ms += r.below(12);
      board.winch.counts += int32_t(r.below(5)) - 1;
      board.winch.load_ready = r.below(10) != 0;
      board.ina.reg[5] = r.below(50) ? board.ina.reg[5] : 0;
      fw.loop();
      board.servos.step(1e-3 * r.below(12));
    }
    // Every decoded host frame got exactly one ACK; the output is clean protocol.
    mrq::FrameDecoder dec;
    mrq::Frame frame;
    uint64_t acks = 0;
    for (size_t i = 0; i < board.serial.tx.size(); ++i) {
      if (dec.push(board.serial.tx[i], &frame) && frame.message.type == mrq::MSG_ACK) ++acks;
    }
    const mrq::DecoderStats& in = fw.rx_stats();
    EXPECT(acks == in.frames - fw.wrong_direction(), "acks %llu for %u host frames\n",
           (unsigned long long)acks, in.frames - fw.wrong_direction());
    const mrq::DecoderStats& out = dec.stats();
    const uint32_t rejects = out.cobs_errors + out.crc_errors + out.short_frames +
                             out.version_errors + out.unknown_types + out.payload_errors +
                             out.range_errors + out.overflows;
    EXPECT(out.frames > 0 && rejects == 0, "the firmware wrote %u frames its decoder rejects\n",
           rejects);
    *acks_out += acks;
  }
  return total;
}

double seconds() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

}  // namespace

int main(int argc, char** argv) {
  uint64_t target = 1000000;
  uint64_t seed = 1;
  for (int i = 1; i < argc; ++i) {
    if (!strcmp(argv[i], "--bytes") && i + 1 < argc) target = strtoull(argv[++i], 0, 10);
    else if (!strcmp(argv[i], "--seed") && i + 1 < argc) seed = strtoull(argv[++i], 0, 10);
    else if (!strcmp(argv[i], "--canary-asan")) {
      std::vector<uint8_t> v(8);
      uint8_t* p = &v[0];
      volatile int k = 8;
      p[k] = 1;   // one past the end of a heap block: AddressSanitizer must stop here
      return p[0];
    } else if (!strcmp(argv[i], "--canary-ubsan")) {
      volatile int32_t big = 2147483647;
      volatile int32_t one = 1;
      return int(big + one) > 0;   // signed overflow: UBSan must stop here
    } else {
      fprintf(stderr, "usage: fuzz [--bytes N] [--seed S]\n");
      return 2;
    }
  }
  Rng r(seed);
  const double t0 = seconds();
  uint64_t streams = 0, acks = 0;
  const uint64_t dec_bytes = fuzz_decoder(r, target, &streams);
  const double t1 = seconds();
  const uint64_t cmd_bytes = fuzz_handler(r, target, &acks);
  const double t2 = seconds();
  printf("decoder: %llu bytes in %llu streams, %.2f s\n", (unsigned long long)dec_bytes,
         (unsigned long long)streams, t1 - t0);
  printf("handler: %llu bytes, %llu acks, %.2f s\n", (unsigned long long)cmd_bytes,
         (unsigned long long)acks, t2 - t1);
  printf("%s\n", failures ? "FAILED" : "no findings");
  return failures ? 1 : 0;
}
