"""The plant the compiled firmware drives: the simulated robot's physics, seen through sensors.

With ``--mcu firmware`` the control runs in C++ (src/minirquad_driver/firmware), so the plant
keeps only what the hardware does by itself:

- four XL330s in velocity mode: each follows its Goal Velocity through a first-order lag
  (``SERVO_TAU``) up to the no-load speed, and reports Present Position (1/4096 rev,
  multi-turn) and Present Velocity (0.229 rpm) through its mounting (zero offset, and a
  mirrored sign on the right);
- the winch gearmotor: a PWM duty against the rope tension (a linear torque-speed line,
  stalled when the tension reaches duty x the stall tension; the gearbox does not back-drive),
  its quadrature encoder, and an inline load cell on an HX711 at 80 samples per second;
- the INA219 as a register file: the firmware writes config and calibration, the chip
  computes current and power from them; ``reset_ina219`` is a brown-out (cal back to 0);
- the body, rope, sled and ground of ``SimRobot``, unchanged.

The body model is kinematic (quasi-static, with the burrow motion prescribed by Table II, as
``SimRobot`` always was), so it must know which motion the legs are executing; the firmware
states it (``follow``). That hint moves nothing: the legs move only by the firmware's goal
velocities, and the burrow ends only when the firmware's own sensing says the pose is reached.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from minirquad_driver import ina219
from minirquad_driver.protocol.messages import BurrowMode, Mode

from .burrow import TABLE_II
from .robot import SimRobot
from .winch import WinchSled

SERVO_RATE_LSB = 0.229 * 2.0 * math.pi / 60.0   # rad/s per XL330 velocity unit (0.229 rpm)
SERVO_COUNTS = 4096                               # Present Position per turn
SERVO_TAU = 0.010        # s: the XL330's velocity loop, as a first-order lag (assumption)
SERVO_NO_LOAD = 40.1     # rad/s: 383 rpm at 5 V (ROBOTIS e-manual, XL330-M077)
INA219_POWER_ON_CONFIG = 0x399F                   # TI SBOS448: power-on value; cal is 0


@dataclass(frozen=True)
class RobotBuild:
    """How this robot is put together, as the firmware must be calibrated for it.

    leg_zero: Present Position at leg angle 0 (counts); leg_sign: +1 where a positive servo
    turn moves the leg forward, -1 for the mirrored right side. winch_um_per_count: rope per
    encoder count (a 100:1 micro gearmotor with a 12 CPR encoder on a 5 mm spool). The load
    cell: HX711 counts with a slack rope (tare) and mN per count. ina219_cal: 4096 for the
    0.1 ohm shunt (0.1 mA per current bit).
    """

    leg_zero: tuple[int, int, int, int] = (1024, 3000, 2148, 500)
    leg_sign: tuple[int, int, int, int] = (1, -1, 1, -1)
    winch_um_per_count: float = 26.17994
    load_cell_tare: int = 8400
    load_cell_mn_per_count: float = 0.0046762
    ina219_cal: int = ina219.CAL_32V_2A


@dataclass
class VelocityServo:
    """A leg servo in velocity mode. angle (rad, unwrapped) and velocity (rad/s) are in the
    leg's frame; goal is the commanded leg rate. target is where the firmware is taking the
    leg (for the body model only)."""

    angle: float = 0.0
    velocity: float = 0.0
    goal: float = 0.0
    target: float = 0.0
    max_speed: float = SERVO_NO_LOAD

    def step(self, dt: float) -> None:
        if dt <= 0.0:
            return
        want = max(-self.max_speed, min(self.max_speed, self.goal))
        self.velocity += (want - self.velocity) * (1.0 - math.exp(-dt / SERVO_TAU))
        self.angle += self.velocity * dt

    def hold(self) -> None:
        """Nothing: a velocity-mode servo stops when the firmware commands zero."""


@dataclass
class MotorWinch(WinchSled):
    """The winch driven by a PWM duty (-1..1, + reels in) instead of a speed set-point.

    full_speed: m/s at full duty without load (the firmware's feed-forward assumes the same);
    the inherited stall_tension is the tension that stops the spool at full duty."""

    full_speed: float = 0.08
    duty: float = 0.0
    brake: bool = True

    def reel(self, dt: float) -> None:
        d = 0.0 if self.brake else self.duty
        if d > 0.0:
            v = max(0.0, self.full_speed * (d - self.tension / self.stall_tension))
        else:
            v = self.full_speed * d
        self.stalled = d > 0.0 and v == 0.0
        if self.free_length() - v * dt > 2.0:   # paying out cannot go past the rope end
            v = 0.0
        self.spool_position += v * dt
        self.spool_velocity = v


@dataclass
class LoadCell:
    """An HX711 on the rope's load cell: a conversion every 1/80 s (seq counts them)."""

    build: RobotBuild
    period: float = 1.0 / 80.0
    raw: int = 0
    seq: int = 0
    silent: bool = False          # fault: the converter stops answering
    _next: float = 0.0

    def update(self, t: float, tension: float) -> None:
        while t >= self._next:
            self._next += self.period
            if self.silent:
                continue
            counts = round(tension * 1000.0 / self.build.load_cell_mn_per_count)
            self.raw = max(-(1 << 23), min((1 << 23) - 1, self.build.load_cell_tare + counts))
            self.seq = (self.seq + 1) & 0xFF


@dataclass
class Ina219Chip:
    """The INA219's registers 0x00..0x05; current and power follow the calibration register
    (datasheet: current = shunt x cal / 4096), so a chip reset shows as cal 0."""

    config: int = INA219_POWER_ON_CONFIG
    cal: int = 0

    def registers(self, bus_voltage: float, current: float) -> tuple[int, ...]:
        p = ina219.registers_from(bus_voltage, current, cal=self.cal)
        return (self.config, p.shunt & 0xFFFF, p.bus, p.power, p.current & 0xFFFF, self.cal)

    def write(self, reg: int, value: int) -> None:
        if reg == 0x00:
            self.config = value
        elif reg == 0x05:
            self.cal = value

    def reset(self) -> None:
        self.config, self.cal = INA219_POWER_ON_CONFIG, 0


@dataclass
class PlantRobot(SimRobot):
    """``SimRobot`` whose legs and winch are driven by the firmware's outputs."""

    build: RobotBuild = field(default_factory=RobotBuild)
    winch: WinchSled = field(default_factory=MotorWinch)

    #: the firmware's 0.5 deg arrival tolerance (its legs settle to a 1/4096-turn encoder)
    leg_arrived = math.radians(0.5)

    def __post_init__(self) -> None:
        super().__post_init__()
        self.servos = [VelocityServo() for _ in range(4)]
        self.load_cell = LoadCell(self.build)
        self.ina219 = Ina219Chip()
        self._motion = (int(Mode.IDLE), int(BurrowMode.UNBURROW), False)

    # ------------------------------------------------------------------ firmware outputs
    def drive(self, goal_velocity, winch_duty_permille: int, winch_brake: bool) -> None:
        """Goal Velocity of each servo (0.229 rpm units) and the winch PWM."""
        for s, raw, sign in zip(self.servos, goal_velocity, self.build.leg_sign):
            s.goal = sign * raw * SERVO_RATE_LSB
        w = self.winch
        if isinstance(w, MotorWinch):
            w.duty = winch_duty_permille / 1000.0
            w.brake = winch_brake

    def follow(self, motion_mode: int, burrow_mode: int, unburrowing: bool) -> None:
        """What the firmware says its legs are doing, for the kinematic body model."""
        state = (int(motion_mode), int(burrow_mode), bool(unburrowing))
        if state == self._motion:
            return
        old_mode = self._motion[0]
        self._motion = state
        mode = Mode(state[0])
        if mode in (Mode.BURROW_RETRACT, Mode.BURROW_FINAL) and state[1] in (1, 2, 3):
            if mode != old_mode:
                self._burrow = BurrowMode(state[1]).name
                seq = TABLE_II[self._burrow]
                self._phase_t = 0.0
                self._body_from = (self.h, self.theta_b)
                self._aim(seq.retract if mode == Mode.BURROW_RETRACT else seq.final)
            self._unburrowing = False
        elif mode != Mode.ANCHORED:
            self._burrow = None
        if state[2] and not self._unburrowing:
            self._unburrowing = True
            self._aim((0.0, 0.0))
        if mode == Mode.WALKING:
            self._unburrowing = False
        self.mode = mode

    # ------------------------------------------------------------------ physics
    def _drive_legs(self) -> None:
        """The firmware drives the legs (``drive``); nothing to compute here."""

    def _walk_direction(self) -> int:
        return 1 if sum(s.velocity for s in self.servos) >= 0.0 else -1

    def step(self, dt: float) -> None:
        super().step(dt)
        self.load_cell.update(self.time, self.winch.tension)

    # ------------------------------------------------------------------ sensors
    def servo_readings(self) -> tuple[list[int], list[int]]:
        """Present Position (multi-turn counts) and Present Velocity (0.229 rpm) per servo."""
        pos, vel = [], []
        for s, zero, sign in zip(self.servos, self.build.leg_zero, self.build.leg_sign):
            pos.append(zero + math.floor(sign * s.angle * SERVO_COUNTS / (2.0 * math.pi)))
            vel.append(round(sign * s.velocity / SERVO_RATE_LSB))
        return pos, vel

    def encoder(self) -> int:
        return math.floor(self.winch.spool_position * 1e6 / self.build.winch_um_per_count)

    def ina219_registers(self) -> tuple[int, ...]:
        v, i = self.power_model.bus(self.power)
        return self.ina219.registers(v, i)

    def imu(self) -> tuple[int, int]:
        """Pitch (urad) and pitch rate (mrad/s), as the IMU reports them."""
        pitch = max(-3141593, min(3141593, round(self.theta_b * 1e6)))
        return pitch, max(-32767, min(32767, round(self.pitch_rate * 1e3)))
