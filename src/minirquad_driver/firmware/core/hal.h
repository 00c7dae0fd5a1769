// The hardware-abstraction layer: everything the core needs from a board, and nothing else.
// The Arduino sketch binds it to DynamixelShield, Wire, HX711 and the winch driver; the SITL
// build binds it to the Python plant over a socket; the tests bind it to plain structs.
//
// No call may block for long: the core runs one control cycle per Firmware::loop() and the
// hardware watchdog resets the board if a driver hangs (e.g. a stuck I2C bus).
#ifndef MRQ_HAL_H
#define MRQ_HAL_H

#include <stddef.h>
#include <stdint.h>

namespace mrq {

// Destructors are protected, non-virtual and trivial: the core never deletes a HAL object
// (no heap), and a static HAL object needs no exit-time destructor registration.

class Clock {
 public:
  virtual uint32_t millis() = 0;   // ms since boot, wraps after 49.7 days
 protected:
  ~Clock() = default;
};

class SerialPort {
 public:
  virtual int read() = 0;                                 // next byte, or -1 if none
  virtual size_t writable() = 0;                          // bytes write() takes now
  virtual size_t write(const uint8_t* data, size_t n) = 0;
 protected:
  ~SerialPort() = default;
};

// One XL330 in velocity mode, as its control table reports it.
struct ServoState {
  int32_t position;     // Present Position (132), 1/4096 rev, multi-turn
  int32_t velocity;     // Present Velocity (128), 0.229 rpm
  int16_t current;      // Present Current (126), mA
  uint16_t voltage;     // Present Input Voltage (144), 0.1 V
};

class ServoBus {
 public:
  // Sync-read the four leg servos (leg order); false if any did not answer.
  virtual bool read(ServoState state[4]) = 0;
  // Sync-write Goal Velocity (104) of the four servos, 0.229 rpm.
  virtual bool write_goal_velocity(const int32_t goal[4]) = 0;
 protected:
  ~ServoBus() = default;
};

// 16-bit register access (INA219: big-endian on the bus; the binding returns the value).
class I2cBus {
 public:
  virtual bool read16(uint8_t address, uint8_t reg, uint16_t* value) = 0;
  virtual bool write16(uint8_t address, uint8_t reg, uint16_t value) = 0;
 protected:
  ~I2cBus() = default;
};

// Winch gearmotor with its quadrature encoder and a load cell on an HX711.
class WinchHardware {
 public:
  virtual int32_t encoder() = 0;                    // counts, reel-in positive
  virtual bool load_cell(int32_t* raw) = 0;         // true with a new reading (never waits)
  virtual void drive(int16_t duty_permille, bool brake) = 0;   // +reel in, -pay out
 protected:
  ~WinchHardware() = default;
};

class Imu {
 public:
  // Body pitch (urad, nose up) and its rate (mrad/s); false if no fresh reading.
  virtual bool read(int32_t* pitch, int16_t* pitch_rate) = 0;
 protected:
  ~Imu() = default;
};

class Watchdog {
 public:
  virtual void kick() = 0;   // the hardware watchdog resets the board if not kicked in time
 protected:
  ~Watchdog() = default;
};

struct Hal {
  Clock* clock;
  SerialPort* serial;
  ServoBus* servos;
  I2cBus* i2c;
  WinchHardware* winch;
  Imu* imu;
  Watchdog* watchdog;
};

}  // namespace mrq

#endif
