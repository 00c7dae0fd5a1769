"""Leg servos: the datasheet's torque-speed line, the current it draws, and the power.

The MiniRQuad-class servo is the ROBOTIS Dynamixel XL330-M077-T (MiniRHex's servo) at 5 V.
Datasheet (ROBOTIS e-manual, XL330-M077-T "Specifications"):

    stall torque 0.215 N m at 1.47 A (5.0 V)     no-load speed 383 rev/min (5.0 V)
    gear ratio 77.5 : 1                           standby current 17 mA

A brushed DC motor driven by PWM from a fixed supply V gives, referred to the output shaft,

    tau_max(w) = tau_s (1 - |w| / w0)            (motoring; w0 = 383 rpm = 40.1 rad/s)
    k_t = tau_s / I_s = 0.146 N m/A,  R = V / I_s = 3.40 ohm,  k_e = V / w0 = 0.125 V s/rad

and the supply delivers P = I (R I + k_e w_signed) with I = |tau| / k_t + I0 while the shaft
turns. k_t / k_e = 1.17 is more than a lossless gearbox allows (it would be 1): the three
datasheet points are not one linear motor, which the docs list among the model's limits.
I0, the no-load current, is not published: 0.10 A is an assumption (a micro gearmotor's
typical 5-10 % of stall current), listed with the free parameters. The supply is not
regenerative: a servo braking a load still dissipates R I^2 and is never credited.
Standby (17 mA x 5 V per servo) is the idle draw the paper removes from its energies.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

RPM = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class ServoSpec:
    """A servo at one supply voltage; SI. Each number names its source in `sources`."""

    name: str
    voltage: float            # V
    stall_torque: float       # N m
    stall_current: float      # A
    no_load_speed: float      # rad/s
    no_load_current: float    # A
    standby_current: float    # A
    sources: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        for key in ('voltage', 'stall_torque', 'stall_current', 'no_load_speed'):
            v = getattr(self, key)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f'servo {self.name}: {key} must be a positive number, got {v}')
        for key in ('no_load_current', 'standby_current'):
            v = getattr(self, key)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f'servo {self.name}: {key} must be >= 0, got {v}')

    @property
    def kt(self) -> float:
        """Torque constant at the output, N m/A."""
        return self.stall_torque / self.stall_current

    @property
    def resistance(self) -> float:
        """Winding resistance, ohm (the stall current at the full supply voltage)."""
        return self.voltage / self.stall_current

    @property
    def ke(self) -> float:
        """Back-emf constant at the output, V s/rad."""
        return self.voltage / self.no_load_speed

    def torque_limit(self, speed: float) -> float:
        """Largest torque the servo applies in the direction it turns at |speed| rad/s, N m
        (0 at and beyond the no-load speed)."""
        return max(0.0, self.stall_torque * (1.0 - abs(speed) / self.no_load_speed))

    def speed_at(self, torque: float) -> float:
        """Fastest |speed| (rad/s) at which the servo still applies |torque| N m; 0 when the
        torque is at or beyond stall."""
        return max(0.0, self.no_load_speed * (1.0 - abs(torque) / self.stall_torque))

    def current(self, torque: float, speed: float, stalled: bool = False) -> float:
        """Motor current, A: the torque's share plus the no-load current while turning; a
        stalled servo (its velocity loop saturated, full PWM against a blocked leg) draws
        its stall current."""
        if stalled:
            return self.stall_current
        i = abs(torque) / self.kt + (self.no_load_current if speed != 0.0 else 0.0)
        return min(i, self.stall_current)

    def power(self, torque: float, speed: float, stalled: bool = False) -> float:
        """Electrical power drawn from the supply above standby, W (no regeneration)."""
        i = self.current(torque, speed, stalled)
        emf = 0.0 if stalled else self.ke * abs(speed)
        if torque * speed < 0.0:   # braking: the load drives the motor
            emf = -emf
        return max(0.0, i * (self.resistance * i + emf))

    def scaled(self, stall_factor: float) -> 'ServoSpec':
        """The same servo with stall torque times stall_factor (a sensitivity study; the
        current and speed lines are kept)."""
        return replace(self, name=f'{self.name} x{stall_factor:g} stall torque',
                       stall_torque=self.stall_torque * stall_factor)

    def describe(self) -> dict:
        return {'name': self.name, 'voltage_V': self.voltage,
                'stall_torque_Nm': self.stall_torque, 'stall_current_A': self.stall_current,
                'no_load_speed_rad_s': self.no_load_speed,
                'no_load_current_A': self.no_load_current,
                'standby_current_A': self.standby_current, 'kt_Nm_per_A': self.kt,
                'resistance_ohm': self.resistance, 'ke_V_s_per_rad': self.ke,
                'sources': dict(self.sources)}


_EMANUAL = 'ROBOTIS e-manual, XL330-M077-T specifications (datasheet)'
XL330_M077_5V = ServoSpec(
    name='XL330-M077-T at 5 V', voltage=5.0, stall_torque=0.215, stall_current=1.47,
    no_load_speed=383.0 * RPM, no_load_current=0.10, standby_current=0.017,
    sources=(('voltage', 'MiniRHex-class supply; the datasheet\'s recommended 5.0 V'),
             ('stall_torque', _EMANUAL), ('stall_current', _EMANUAL),
             ('no_load_speed', _EMANUAL), ('standby_current', _EMANUAL),
             ('no_load_current', 'assumed (not published): 0.10 A')))

SERVOS = {'xl330-m077': XL330_M077_5V}
