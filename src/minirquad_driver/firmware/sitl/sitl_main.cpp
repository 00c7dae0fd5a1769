// fw_sitl: the firmware core on a HAL whose hardware is the simulated plant.
//
//   fw_sitl --fd N [--clock-start-ms MS] [--telemetry-hz H] [--power-hz H]
//           [--watchdog-ms MS] [--winch-deadman-ms MS]
//
// N is this end of a SOCK_SEQPACKET socketpair whose other end the plant (minirquad_sim)
// holds. Per PlantFrame received: the HAL takes its sensor values and serial bytes, the core
// runs one loop() (the first frame after a start or a reset runs begin() instead, as an
// Arduino's setup()), and a FwFrame goes back with the outputs and the serial bytes written.
// The core is re-created on CMD_RESET (the hardware watchdog's or a brown-out's reset: clock and
// sequence numbers from zero, RESET_NOTICE with the given cause). Exits when the plant closes
// the socket.
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <new>

#include "../core/config.h"
#include "../core/firmware.h"
#include "sitl_link.h"

namespace {

struct SitlClock : mrq::Clock {
  uint32_t ms;
  uint32_t millis() override { return ms; }
};

struct SitlSerial : mrq::SerialPort {
  const uint8_t* rx;
  size_t rx_len, rx_pos;
  uint8_t tx[sitl::MAX_SERIAL];
  size_t tx_len;
  int read() override { return rx_pos < rx_len ? rx[rx_pos++] : -1; }
  size_t writable() override { return sizeof(tx) - tx_len; }
  size_t write(const uint8_t* d, size_t n) override {
    if (n > writable()) n = writable();
    memcpy(tx + tx_len, d, n);
    tx_len += n;
    return n;
  }
};

struct SitlServos : mrq::ServoBus {
  const sitl::PlantFrame* in;
  int32_t goal[4];
  bool read(mrq::ServoState s[4]) override {
    for (int i = 0; i < 4; ++i) {
      s[i].position = in->servo_position[i];
      s[i].velocity = in->servo_velocity[i];
      s[i].current = in->servo_current[i];
      s[i].voltage = in->servo_voltage[i];
    }
    return (in->servo_ok & 0x0F) == 0x0F;
  }
  bool write_goal_velocity(const int32_t g[4]) override {
    memcpy(goal, g, sizeof(goal));
    return true;
  }
};

// The INA219 as a register file: reads see the plant's registers and this exchange's
// writes; the writes go back to the plant, which computes the next conversion with them.
struct SitlIna219 : mrq::I2cBus {
  uint8_t address;
  bool ok;
  uint16_t reg[6];
  uint8_t writes;
  uint8_t write_reg[4];
  uint16_t write_value[4];
  bool read16(uint8_t a, uint8_t r, uint16_t* v) override {
    if (!ok || a != address || r > 5) return false;
    *v = reg[r];
    return true;
  }
  bool write16(uint8_t a, uint8_t r, uint16_t v) override {
    if (!ok || a != address || r > 5 || writes == 4) return false;
    reg[r] = v;
    write_reg[writes] = r;
    write_value[writes] = v;
    ++writes;
    return true;
  }
};

struct SitlWinch : mrq::WinchHardware {
  const sitl::PlantFrame* in;
  uint8_t seen_seq;
  int16_t duty;
  bool brake;
  int32_t encoder() override { return in->winch_encoder; }
  bool load_cell(int32_t* raw) override {   // a conversion is read once, as from an HX711
    if (in->load_cell_seq == seen_seq) return false;
    seen_seq = in->load_cell_seq;
    *raw = in->load_cell_raw;
    return true;
  }
  void drive(int16_t d, bool b) override {
    duty = d;
    brake = b;
  }
};

struct SitlImu : mrq::Imu {
  const sitl::PlantFrame* in;
  bool read(int32_t* p, int16_t* r) override {
    *p = in->pitch;
    *r = in->pitch_rate;
    return in->imu_ok != 0;
  }
};

struct SitlWatchdog : mrq::Watchdog {
  bool kicked;
  void kick() override { kicked = true; }
};

[[noreturn]] void die(const char* what) {
  fprintf(stderr, "fw_sitl: %s\n", what);
  exit(2);
}

long arg_value(int argc, char** argv, const char* name, long fallback) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (!strcmp(argv[i], name)) return strtol(argv[i + 1], 0, 0);
  }
  return fallback;
}

}  // namespace

int main(int argc, char** argv) {
  const long fd = arg_value(argc, argv, "--fd", -1);
  if (fd < 0) die("usage: fw_sitl --fd N [--clock-start-ms MS] [--telemetry-hz H] ...");
  mrq::Config config = mrq::default_config();
  config.telemetry_hz = uint16_t(arg_value(argc, argv, "--telemetry-hz", config.telemetry_hz));
  config.power_hz = uint16_t(arg_value(argc, argv, "--power-hz", config.power_hz));
  config.host_watchdog_ms = uint16_t(arg_value(argc, argv, "--watchdog-ms",
                                               config.host_watchdog_ms));
  config.winch_deadman_ms = uint16_t(arg_value(argc, argv, "--winch-deadman-ms",
                                               config.winch_deadman_ms));
  // One control cycle per telemetry sample at least (up to 1 kHz).
  if (config.telemetry_hz > 1000 / config.control_period_ms) {
    const long period = 1000 / long(config.telemetry_hz);
    config.control_period_ms = uint16_t(period < 1 ? 1 : period);
  }
  // strtoul keeps values up to 0xFFFFFFFF (e.g. 0xFFFFF000 to cross the wrap).
  uint32_t clock_start = 0;
  for (int i = 1; i + 1 < argc; ++i) {
    if (!strcmp(argv[i], "--clock-start-ms")) clock_start = uint32_t(strtoul(argv[i + 1], 0, 0));
  }

  sitl::Hello hello;
  memset(&hello, 0, sizeof(hello));
  hello.magic = sitl::HELLO_MAGIC;
  hello.version = sitl::VERSION;
  hello.size = sizeof(hello);
  for (int i = 0; i < 4; ++i) {
    hello.leg_zero[i] = config.legs[i].zero;
    hello.leg_sign[i] = config.legs[i].sign;
  }
  hello.winch_um_per_count = config.winch_um_per_count;
  hello.load_cell_tare = config.load_cell_tare;
  hello.load_cell_mn_per_count = config.load_cell_mn_per_count;
  hello.ina219_cal = config.ina219_cal;
  hello.control_period_ms = config.control_period_ms;
  if (send(int(fd), &hello, sizeof(hello), 0) != ssize_t(sizeof(hello))) die("hello not sent");

  static SitlClock clock_hw;
  static SitlSerial serial_hw;
  static SitlServos servos_hw;
  static SitlIna219 ina_hw;
  static SitlWinch winch_hw;
  static SitlImu imu_hw;
  static SitlWatchdog watchdog_hw;
  const mrq::Hal hal = {&clock_hw, &serial_hw, &servos_hw, &ina_hw, &winch_hw, &imu_hw,
                        &watchdog_hw};
  ina_hw.address = config.ina219_address;
  // The core lives in static storage and is re-created in place on a reset (no heap).
  alignas(mrq::Firmware) static unsigned char storage[sizeof(mrq::Firmware)];
  mrq::Firmware* fw = 0;
  uint64_t boot_us = 0;
  uint32_t clock_offset = clock_start;

  static uint8_t in_buf[sizeof(sitl::PlantFrame) + sitl::MAX_SERIAL];
  static uint8_t out_buf[sizeof(sitl::FwFrame) + sitl::MAX_SERIAL];
  for (;;) {
    const ssize_t n = recv(int(fd), in_buf, sizeof(in_buf), 0);
    if (n == 0) return 0;   // the plant is gone
    if (n < 0) {
      if (errno == EINTR) continue;
      die("recv failed");
    }
    sitl::PlantFrame in;
    if (size_t(n) < sizeof(in)) die("short plant frame");
    memcpy(&in, in_buf, sizeof(in));
    if (in.magic != sitl::PLANT_MAGIC || in.version != sitl::VERSION || in.size != sizeof(in) ||
        size_t(n) != sizeof(in) + in.rx_len || in.rx_len > sitl::MAX_SERIAL) {
      die("plant frame layout mismatch");
    }
    servos_hw.in = &in;
    winch_hw.in = &in;
    imu_hw.in = &in;
    ina_hw.ok = in.ina219_ok != 0;
    memcpy(ina_hw.reg, in.ina219, sizeof(ina_hw.reg));
    ina_hw.writes = 0;
    serial_hw.rx = in_buf + sizeof(in);
    serial_hw.rx_len = in.rx_len;
    serial_hw.rx_pos = 0;
    serial_hw.tx_len = 0;
    watchdog_hw.kicked = false;

    const bool reset = in.command == sitl::CMD_RESET;
    if (!fw || reset) {
      if (fw) fw->~Firmware();
      if (reset) clock_offset = 0;   // a reboot restarts the clock from zero
      boot_us = in.sim_us;
      clock_hw.ms = clock_offset;
      winch_hw.seen_seq = uint8_t(in.load_cell_seq - 1);   // the latest reading is new
      memset(servos_hw.goal, 0, sizeof(servos_hw.goal));
      winch_hw.duty = 0;
      winch_hw.brake = true;
      fw = new (storage) mrq::Firmware(hal, config);
      fw->begin(reset ? in.reset_cause : uint8_t(mrq::RESET_POWER_ON));   // setup()
    } else {
      clock_hw.ms = clock_offset + uint32_t((in.sim_us - boot_us) / 1000u);
      fw->loop();                                                          // loop()
    }

    sitl::FwFrame out;
    memset(&out, 0, sizeof(out));
    out.magic = sitl::FW_MAGIC;
    out.version = sitl::VERSION;
    out.size = sizeof(out);
    out.frame = in.frame;
    out.fw_ms = clock_hw.ms;
    out.next_due_ms = fw->next_due();
    memcpy(out.goal_velocity, servos_hw.goal, sizeof(out.goal_velocity));
    out.winch_duty = winch_hw.duty;
    out.winch_brake = winch_hw.brake ? 1 : 0;
    out.watchdog_kicked = watchdog_hw.kicked ? 1 : 0;
    out.ina219_writes = ina_hw.writes;
    memcpy(out.ina219_reg, ina_hw.write_reg, sizeof(out.ina219_reg));
    memcpy(out.ina219_value, ina_hw.write_value, sizeof(out.ina219_value));
    out.motion_mode = fw->mode();
    out.burrow_mode = fw->burrow_mode();
    out.unburrowing = fw->unburrowing() ? 1 : 0;
    out.next_seq = fw->next_seq();
    const mrq::DecoderStats& s = fw->rx_stats();
    out.rx_frames = s.frames;
    out.rx_rejected = s.cobs_errors + s.crc_errors + s.short_frames + s.version_errors +
                      s.unknown_types + s.payload_errors + s.range_errors + s.overflows;
    out.rx_crc_errors = s.crc_errors;
    out.tx_dropped = fw->tx_dropped();
    out.tx_len = uint16_t(serial_hw.tx_len);
    memcpy(out_buf, &out, sizeof(out));
    memcpy(out_buf + sizeof(out), serial_hw.tx, serial_hw.tx_len);
    const size_t len = sizeof(out) + serial_hw.tx_len;
    if (send(int(fd), out_buf, len, 0) != ssize_t(len)) die("send failed");
  }
}
