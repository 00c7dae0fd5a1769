#include "power_monitor.h"

namespace mrq {

bool PowerMonitor::begin(I2cBus& bus) {
  const uint8_t a = config_.ina219_address;
  if (bus.write16(a, INA219_CONFIG, config_.ina219_config) &&
      bus.write16(a, INA219_CALIBRATION, config_.ina219_cal)) {
    return true;
  }
  ++i2c_errors_;
  return false;
}

bool PowerMonitor::sample(I2cBus& bus, Power* out) {
  const uint8_t a = config_.ina219_address;
  uint16_t cal, bus_v, shunt, current, power;
  // Cal first, then the measurements back to back (one conversion's worth at 400 kHz).
  if (!bus.read16(a, INA219_CALIBRATION, &cal) || !bus.read16(a, INA219_BUS, &bus_v) ||
      !bus.read16(a, INA219_SHUNT, &shunt) || !bus.read16(a, INA219_CURRENT, &current) ||
      !bus.read16(a, INA219_POWER, &power)) {
    ++i2c_errors_;
    return false;
  }
  out->cal = cal;
  out->bus = bus_v;
  out->shunt = int16_t(shunt);
  out->current = int16_t(current);
  out->power = power;
  if (cal == 0) {   // the chip reset: report it as read, restore it for the next sample
    ++rewrites_;
    begin(bus);
  }
  return true;
}

}  // namespace mrq
