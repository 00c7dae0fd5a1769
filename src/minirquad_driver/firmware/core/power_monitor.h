// INA219 sampling for the POWER frame: the raw registers, cal read back as it is.
//
// Calibration is read first and reported as read: 0 means the chip reset (a load spike can
// brown it out), which the host counts and works around (shunt / R). Only then are config
// and calibration rewritten, for the next sample. Adafruit's library rewrites calibration
// before every read instead, which hides exactly those resets.
#ifndef MRQ_POWER_MONITOR_H
#define MRQ_POWER_MONITOR_H

#include <stdint.h>

#include "config.h"
#include "hal.h"
#include "messages.h"

namespace mrq {

enum Ina219Register {
  INA219_CONFIG = 0x00, INA219_SHUNT = 0x01, INA219_BUS = 0x02, INA219_POWER = 0x03,
  INA219_CURRENT = 0x04, INA219_CALIBRATION = 0x05
};

class PowerMonitor {
 public:
  explicit PowerMonitor(const Config& config) : config_(config), i2c_errors_(0), rewrites_(0) {}
  bool begin(I2cBus& bus);                // write config and calibration
  // Read one sample; false (nothing to send) if the bus failed.
  bool sample(I2cBus& bus, Power* out);
  uint32_t i2c_errors() const { return i2c_errors_; }
  uint32_t rewrites() const { return rewrites_; }   // calibrations restored after a reset

 private:
  const Config& config_;
  uint32_t i2c_errors_;
  uint32_t rewrites_;
};

}  // namespace mrq

#endif
