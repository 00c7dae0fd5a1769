// A HAL made of plain state for unit tests and the fuzz harness: a settable clock, a serial
// port with byte queues, servos that integrate their goal velocity, a register-file INA219,
// a winch with settable sensors. Header-only; host code (may use the C++ library).
#ifndef MRQ_TESTS_FAKE_HAL_H
#define MRQ_TESTS_FAKE_HAL_H

#include <stdint.h>
#include <string.h>

#include <deque>
#include <vector>

#include "../core/frame.h"
#include "../core/hal.h"
#include "../core/legs.h"

namespace fake {

struct Clock : mrq::Clock {
  uint32_t ms = 0;
  uint32_t millis() override { return ms; }
};

struct Serial : mrq::SerialPort {
  std::deque<uint8_t> rx;
  std::vector<uint8_t> tx;
  size_t space = 1 << 20;
  int read() override {
    if (rx.empty()) return -1;
    const int c = rx.front();
    rx.pop_front();
    return c;
  }
  size_t writable() override { return space; }
  size_t write(const uint8_t* d, size_t n) override {
    tx.insert(tx.end(), d, d + n);
    return n;
  }
  void feed(const std::vector<uint8_t>& bytes) { rx.insert(rx.end(), bytes.begin(), bytes.end()); }
};

// Servos that follow their goal velocity exactly (position in float counts).
struct Servos : mrq::ServoBus {
  double pos[4] = {0, 0, 0, 0};
  int32_t goal[4] = {0, 0, 0, 0};
  bool ok = true;
  int writes = 0;
  bool read(mrq::ServoState s[4]) override {
    for (int i = 0; i < 4; ++i) {
      s[i].position = int32_t(pos[i] >= 0 ? pos[i] : pos[i] - 1);   // floor
      s[i].velocity = goal[i];
      s[i].current = 0;
      s[i].voltage = 74;
    }
    return ok;
  }
  bool write_goal_velocity(const int32_t g[4]) override {
    memcpy(goal, g, sizeof(goal));
    ++writes;
    return true;
  }
  void step(double dt) {   // counts per second = raw * 0.229 rpm * 4096 / 60
    for (int i = 0; i < 4; ++i) pos[i] += goal[i] * 0.229 * 4096.0 / 60.0 * dt;
  }
};

struct Ina219 : mrq::I2cBus {
  uint16_t reg[6] = {0x399F, 1234, (1850 << 3) | 2, 456, 1234, 0};
  bool ok = true;
  int writes = 0;
  bool read16(uint8_t, uint8_t r, uint16_t* v) override {
    if (!ok || r > 5) return false;
    *v = reg[r];
    return true;
  }
  bool write16(uint8_t, uint8_t r, uint16_t v) override {
    if (!ok || r > 5) return false;
    reg[r] = v;
    ++writes;
    return true;
  }
};

struct Winch : mrq::WinchHardware {
  int32_t counts = 0;
  int32_t load = 8400;      // the default tare: zero tension
  bool load_ready = true;
  int16_t duty = 0;
  bool brake = true;
  int32_t encoder() override { return counts; }
  bool load_cell(int32_t* raw) override {
    if (!load_ready) return false;
    *raw = load;
    return true;
  }
  void drive(int16_t d, bool b) override {
    duty = d;
    brake = b;
  }
};

struct Imu : mrq::Imu {
  int32_t pitch = 0;
  int16_t rate = 0;
  bool ok = true;
  bool read(int32_t* p, int16_t* r) override {
    *p = pitch;
    *r = rate;
    return ok;
  }
};

struct Watchdog : mrq::Watchdog {
  uint32_t kicks = 0;
  void kick() override { ++kicks; }
};

struct Board {
  Clock clock;
  Serial serial;
  Servos servos;
  Ina219 ina;
  Winch winch;
  Imu imu;
  Watchdog watchdog;
  mrq::Hal hal() {
    mrq::Hal h = {&clock, &serial, &servos, &ina, &winch, &imu, &watchdog};
    return h;
  }
};

// Frames the firmware wrote, decoded with the C++ decoder.
inline std::vector<mrq::Frame> drain(Serial& s) {
  std::vector<mrq::Frame> out;
  mrq::FrameDecoder dec;
  mrq::Frame f;
  for (size_t i = 0; i < s.tx.size(); ++i) {
    if (dec.push(s.tx[i], &f)) out.push_back(f);
  }
  s.tx.clear();
  return out;
}

inline std::vector<uint8_t> wire(const mrq::Message& m, uint8_t seq, uint32_t t = 0) {
  uint8_t buf[mrq::MAX_WIRE];
  const size_t n = mrq::encode_frame(m, seq, t, buf, sizeof(buf));
  return std::vector<uint8_t>(buf, buf + n);
}

}  // namespace fake

#endif
