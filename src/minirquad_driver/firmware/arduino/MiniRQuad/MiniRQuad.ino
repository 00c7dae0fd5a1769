// MiniRQuad firmware for the Arduino MKR WiFi 1010: the portable core (src/core, copied in by
// `make sketch`) bound to the real parts in board.h. The protocol is PROTOCOL.md of the
// minirquad_driver package; the host side is its bridge_node.
#include "board.h"
#include "src/core/config.h"
#include "src/core/firmware.h"

// Measure each leg's zero (Present Position with the leg pointing straight down) and enter
// it below, then set this to 1. Until then the sketch refuses to build: a wrong zero turns a
// gait into legs fighting the sand.
#define LEG_ZEROS_MEASURED 0
#if !LEG_ZEROS_MEASURED
#error "enter this robot's leg zeros and load-cell calibration in MiniRQuad.ino"
#endif

UsbSerial serial_port;
MillisClock clock_source;
XL330Bus servos;
Ina219Wire ina219;
WinchParts winch;
ImuShield imu;
HardwareWatchdog watchdog;

mrq::Config robot_config() {
  mrq::Config c = mrq::default_config();
  const mrq::LegMount legs[4] = {{0, 1}, {0, -1}, {0, 1}, {0, -1}};   // zero, sign per leg
  for (int i = 0; i < 4; ++i) c.legs[i] = legs[i];
  c.load_cell_tare = 0;              // HX711 raw with a slack rope
  c.load_cell_mn_per_count = 0.0f;   // from a known weight hung on the rope
  return c;
}

const mrq::Config config = robot_config();
const mrq::Hal hal = {&clock_source, &serial_port, &servos, &ina219, &winch, &imu, &watchdog};
mrq::Firmware firmware(hal, config);

uint8_t reset_cause() {              // the SAMD21's reset cause register (PM->RCAUSE)
  const uint8_t r = Watchdog.resetCause();
  if (r & PM_RCAUSE_WDT) return mrq::RESET_WATCHDOG;
  if (r & (PM_RCAUSE_BOD12 | PM_RCAUSE_BOD33)) return mrq::RESET_BROWNOUT;
  if (r & PM_RCAUSE_SYST) return mrq::RESET_SOFTWARE;
  if (r & PM_RCAUSE_POR) return mrq::RESET_POWER_ON;
  return mrq::RESET_UNKNOWN;
}

void setup() {
  Watchdog.enable(250);              // longer than any legitimate block (a USB write: 70 ms)
  Serial.begin(115200);              // USB CDC: the baud rate is ignored
  Wire.begin();
  Wire.setClock(400000);             // five INA219 registers in 0.6 ms
  winch.begin();
  IMU.begin();
  servos.begin();
  firmware.begin(reset_cause());
}

void loop() { firmware.loop(); }
