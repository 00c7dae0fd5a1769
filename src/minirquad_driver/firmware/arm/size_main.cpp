// The firmware core on a stub HAL, for the size check only. Every HAL call reads or writes a
// volatile "register", so the optimiser can drop none of the core's code.
#include <stdint.h>

#include "../core/config.h"
#include "../core/firmware.h"

namespace {

volatile uint32_t reg[16];

struct StubClock : mrq::Clock {
  uint32_t millis() { return reg[0]; }
};
struct StubSerial : mrq::SerialPort {
  int read() { return reg[1] & 0x100 ? -1 : int(reg[1] & 0xFF); }
  size_t writable() { return reg[2]; }
  size_t write(const uint8_t* d, size_t n) {
    for (size_t i = 0; i < n; ++i) reg[3] = d[i];
    return n;
  }
};
struct StubServos : mrq::ServoBus {
  bool read(mrq::ServoState s[4]) {
    for (int i = 0; i < 4; ++i) {
      s[i].position = int32_t(reg[4]);
      s[i].velocity = int32_t(reg[5]);
      s[i].current = int16_t(reg[6]);
      s[i].voltage = uint16_t(reg[6] >> 16);
    }
    return reg[7] != 0;
  }
  bool write_goal_velocity(const int32_t g[4]) {
    for (int i = 0; i < 4; ++i) reg[8] = uint32_t(g[i]);
    return true;
  }
};
struct StubI2c : mrq::I2cBus {
  bool read16(uint8_t a, uint8_t r, uint16_t* v) {
    reg[9] = uint32_t(a) << 8 | r;
    *v = uint16_t(reg[10]);
    return reg[11] != 0;
  }
  bool write16(uint8_t a, uint8_t r, uint16_t v) {
    reg[9] = uint32_t(a) << 24 | uint32_t(r) << 16 | v;
    return reg[11] != 0;
  }
};
struct StubWinch : mrq::WinchHardware {
  int32_t encoder() { return int32_t(reg[12]); }
  bool load_cell(int32_t* raw) {
    *raw = int32_t(reg[13]);
    return reg[14] != 0;
  }
  void drive(int16_t duty, bool brake) { reg[15] = uint32_t(duty) | (brake ? 0x10000u : 0); }
};
struct StubImu : mrq::Imu {
  bool read(int32_t* p, int16_t* r) {
    *p = int32_t(reg[4]);
    *r = int16_t(reg[5]);
    return reg[7] != 0;
  }
};
struct StubWatchdog : mrq::Watchdog {
  void kick() { reg[0] = reg[0]; }
};

StubClock clock_hw;
StubSerial serial_hw;
StubServos servos_hw;
StubI2c i2c_hw;
StubWinch winch_hw;
StubImu imu_hw;
StubWatchdog watchdog_hw;
const mrq::Config config = mrq::default_config();
const mrq::Hal hal = {&clock_hw, &serial_hw, &servos_hw, &i2c_hw, &winch_hw, &imu_hw,
                      &watchdog_hw};
mrq::Firmware firmware(hal, config);

}  // namespace

int main() {
  firmware.begin(uint8_t(reg[1]));
  for (;;) firmware.loop();
}
