// The HAL bound to the MiniRQuad's real parts (MKR WiFi 1010 + DYNAMIXEL Shield for MKR):
// DynamixelShield (Dynamixel2Arduino) for the four XL330s, Wire for the INA219, a DRV8871-style
// H-bridge and a quadrature encoder for the winch gearmotor, bogde's HX711 for the load cell,
// Arduino_MKRIMU (BNO055 shield) for pitch, Adafruit_SleepyDog to arm the hardware watchdog.
// Not compiled by this repository's tests (no Arduino core here); see ../../README.md.
#ifndef MINIRQUAD_BOARD_H
#define MINIRQUAD_BOARD_H

#include <Adafruit_SleepyDog.h>
#include <Arduino_MKRIMU.h>
#include <DynamixelShield.h>
#include <HX711.h>
#include <Wire.h>

#include "src/core/hal.h"

namespace pins {
const uint8_t ENCODER_A = 0, ENCODER_B = 1;   // interrupt-capable on the MKR
const uint8_t HX711_DOUT = 2, HX711_SCK = 3;
const uint8_t WINCH_IN1 = 4, WINCH_IN2 = 5;   // PWM
}  // namespace pins

const uint8_t SERVO_IDS[4] = {1, 2, 3, 4};    // leg order: PL, PR, DL, DR
const float IMU_PITCH_SIGN = 1.0f;            // +1 if the shield's pitch is nose-up positive

struct UsbSerial : mrq::SerialPort {
  int read() override { return Serial.read(); }
  // The SAMD USB CDC blocks a write until the host takes it; with no host attached the
  // frames are dropped instead of stalling the control loop.
  size_t writable() override { return Serial ? 256 : 0; }
  size_t write(const uint8_t* d, size_t n) override { return Serial.write(d, n); }
};

struct MillisClock : mrq::Clock {
  uint32_t millis() override { return ::millis(); }
};

// Sync read of 126..135 (current, velocity, position) and sync write of Goal Velocity (104),
// with the library's "Info" structs over caller-owned buffers (no heap after set-up).
struct XL330Bus : mrq::ServoBus {
  DynamixelShield dxl;
  struct __attribute__((packed)) Present { int16_t current; int32_t velocity; int32_t position; };
  Present present[4];
  int32_t goal[4];
  uint8_t packet[128];
  DYNAMIXEL::InfoSyncReadInst_t rd;
  DYNAMIXEL::XELInfoSyncRead_t rd_xel[4];
  DYNAMIXEL::InfoSyncWriteInst_t wr;
  DYNAMIXEL::XELInfoSyncWrite_t wr_xel[4];

  void begin() {
    dxl.begin(1000000);                      // servos set to 1 Mbps beforehand (1.4 ms cycle)
    dxl.setPortProtocolVersion(2.0);
    for (int i = 0; i < 4; ++i) {
      const uint8_t id = SERVO_IDS[i];
      dxl.torqueOff(id);
      dxl.setOperatingMode(id, OP_VELOCITY);
      dxl.writeControlTableItem(ControlTableItem::RETURN_DELAY_TIME, id, 0);
      // Bus watchdog 100 ms: a hung MCU stops the legs. Goals written 0 clear a trip.
      dxl.writeControlTableItem(ControlTableItem::BUS_WATCHDOG, id, 0);
      dxl.writeControlTableItem(ControlTableItem::BUS_WATCHDOG, id, 5);
      dxl.torqueOn(id);
      rd_xel[i].id = wr_xel[i].id = id;
      rd_xel[i].p_recv_buf = reinterpret_cast<uint8_t*>(&present[i]);
      wr_xel[i].p_data = reinterpret_cast<uint8_t*>(&goal[i]);
    }
    rd.packet.p_buf = packet;
    rd.packet.buf_capacity = sizeof(packet);
    rd.packet.is_completed = false;
    rd.addr = 126;
    rd.addr_length = 10;
    rd.p_xels = rd_xel;
    rd.xel_count = 4;
    rd.is_info_changed = true;
    wr.packet.p_buf = nullptr;               // the library's own buffer, allocated at begin()
    wr.packet.is_completed = false;
    wr.addr = 104;
    wr.addr_length = 4;
    wr.p_xels = wr_xel;
    wr.xel_count = 4;
    wr.is_info_changed = true;
  }
  bool read(mrq::ServoState s[4]) override {
    if (dxl.syncRead(&rd) != 4) return false;
    for (int i = 0; i < 4; ++i) {
      s[i].position = present[i].position;
      s[i].velocity = present[i].velocity;
      s[i].current = present[i].current;
      s[i].voltage = 0;                      // not read every cycle
    }
    return true;
  }
  bool write_goal_velocity(const int32_t g[4]) override {
    memcpy(goal, g, sizeof(goal));
    wr.is_info_changed = true;
    return dxl.syncWrite(&wr);
  }
};

struct Ina219Wire : mrq::I2cBus {
  bool read16(uint8_t a, uint8_t reg, uint16_t* v) override {
    Wire.beginTransmission(a);
    Wire.write(reg);
    if (Wire.endTransmission(false) != 0 || Wire.requestFrom(a, uint8_t(2)) != 2) return false;
    const uint8_t hi = Wire.read();
    *v = uint16_t(hi << 8 | Wire.read());    // the INA219 sends its registers MSB first
    return true;
  }
  bool write16(uint8_t a, uint8_t reg, uint16_t v) override {
    Wire.beginTransmission(a);
    Wire.write(reg);
    Wire.write(uint8_t(v >> 8));
    Wire.write(uint8_t(v));
    return Wire.endTransmission() == 0;
  }
};

volatile int32_t encoder_counts = 0;
inline void on_encoder() {                   // both edges of A and B: 4x quadrature
  static uint8_t last = 0;
  const uint8_t now = uint8_t(digitalRead(pins::ENCODER_A) << 1 | digitalRead(pins::ENCODER_B));
  static const int8_t step[16] = {0, -1, 1, 0, 1, 0, 0, -1, -1, 0, 0, 1, 0, 1, -1, 0};
  encoder_counts += step[last << 2 | now];
  last = now;
}

struct WinchParts : mrq::WinchHardware {
  HX711 cell;
  void begin() {
    pinMode(pins::WINCH_IN1, OUTPUT);
    pinMode(pins::WINCH_IN2, OUTPUT);
    drive(0, true);
    pinMode(pins::ENCODER_A, INPUT_PULLUP);
    pinMode(pins::ENCODER_B, INPUT_PULLUP);
    attachInterrupt(digitalPinToInterrupt(pins::ENCODER_A), on_encoder, CHANGE);
    attachInterrupt(digitalPinToInterrupt(pins::ENCODER_B), on_encoder, CHANGE);
    cell.begin(pins::HX711_DOUT, pins::HX711_SCK);   // gain 128, channel A
  }
  int32_t encoder() override {
    noInterrupts();
    const int32_t c = encoder_counts;
    interrupts();
    return c;
  }
  bool load_cell(int32_t* raw) override {    // read() only when ready: it never waits
    if (!cell.is_ready()) return false;
    *raw = cell.read();
    return true;
  }
  void drive(int16_t duty, bool brake) override {
    if (brake || duty == 0) {                // both inputs high: the bridge brakes
      digitalWrite(pins::WINCH_IN1, HIGH);
      digitalWrite(pins::WINCH_IN2, HIGH);
      return;
    }
    const int pwm = (duty > 0 ? duty : -duty) * 255 / 1000;
    analogWrite(duty > 0 ? pins::WINCH_IN1 : pins::WINCH_IN2, pwm);
    digitalWrite(duty > 0 ? pins::WINCH_IN2 : pins::WINCH_IN1, LOW);
  }
};

struct ImuShield : mrq::Imu {
  bool read(int32_t* pitch, int16_t* rate) override {
    float heading, roll, p, gx, gy, gz;
    if (!IMU.eulerAnglesAvailable() || !IMU.readEulerAngles(heading, roll, p)) return false;
    if (!IMU.gyroscopeAvailable() || !IMU.readGyroscope(gx, gy, gz)) return false;
    *pitch = int32_t(IMU_PITCH_SIGN * p * 17453.29f);       // deg -> urad
    *rate = int16_t(IMU_PITCH_SIGN * gy * 17.45329f);       // deg/s -> mrad/s
    return true;
  }
};

// Clear the SAMD21 watchdog only when its registers are synchronised: waiting for the
// synchronisation at every clear (as Watchdog.reset() does) stalls the loop for milliseconds.
struct HardwareWatchdog : mrq::Watchdog {
  void kick() override {
    if (!WDT->STATUS.bit.SYNCBUSY) WDT->CLEAR.reg = WDT_CLEAR_CLEAR_KEY;
  }
};

#endif
