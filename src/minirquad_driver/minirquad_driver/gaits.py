"""Named gaits the host can select on /gait, carried to the MCU as data (SET_GAIT), and how
long a commanded gait may run (``GaitHold``).

Four-leg versions of the MiniRHex Buehler-clock gaits (period, duty, sweep, down, phase
per leg in PL, PR, DL, DR order). Walk timing follows MiniRHex's walk (2 s, duty 0.42,
sweep 40 deg, down 20 deg). MiniRHex's angles grow as its legs walk it forward; the
protocol's grow toe forward (away from p), so its stance centre, 20 deg toe back, is down
-20 deg here, and the clock (gait_clock.cpp) sweeps the toes back in stance.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .protocol.messages import GaitKind, SetGait

_WALK = dict(period=2.0, duty=0.42, sweep=math.radians(40.0), down=math.radians(-20.0))

GAITS: dict[str, SetGait] = {
    'stand': SetGait(GaitKind.STAND, down=0.0),
    # Trot: diagonal pairs in antiphase (PL with DR, PR with DL).
    'walk': SetGait(GaitKind.CLOCK, phases=(0.0, 0.5, 0.5, 0.0), **_WALK),
    'reverse': SetGait(GaitKind.CLOCK, phases=(0.0, 0.5, 0.5, 0.0), direction=-1, **_WALK),
    # Bound: front pair against rear pair.
    'bound': SetGait(GaitKind.CLOCK, phases=(0.0, 0.0, 0.5, 0.5), **_WALK),
}


@dataclass
class GaitHold:
    """The named gait the MCU was last sent and until when it may run (s, ROS time; inf: until
    told otherwise), as the bridge keeps it.

    A commander that walks the robot (GaitCommand with ``valid_until``) refreshes the command
    while it wants the gait; one that stops (crashed, stalled) has the robot stand at the
    deadline, as the MCU's winch deadman stops the payout that goes with a walk, so the robot
    does not walk on into a braked tether. The MCU's own 500 ms watchdog covers a bridge that
    stops. A refresh of the gait that runs sends nothing (a new SET_GAIT would restart the
    clock's phase); a different gait, or any gait after the MCU left it (legs, burrow, e-stop,
    stop: ``left``), is sent. A gait command sent before the bridge received the command that
    made the MCU leave the gait is dropped: DDS orders messages per topic, not across topics,
    so a walk refresh published just before a burrow can arrive after it, and must not walk
    the robot out of its burrow.
    """

    running: str | None = None
    until: float = math.inf
    left_at: float = -math.inf   # s, ROS time: when a command last made the MCU leave the gait

    @property
    def moving(self) -> bool:
        return self.running not in (None, 'stand')

    def command(self, name: str, valid_until: float, now: float,
                sent_at: float = 0.0) -> str | None:
        """The gait to send for a command of ``name`` valid until ``valid_until`` (s, 0: no
        limit) received at ``now`` and sent at ``sent_at`` (its header stamp; 0: unknown);
        None when there is nothing to send. A moving gait already past its deadline never
        starts one (and stands a moving robot); one sent before the last ``left`` is dropped."""
        if 0.0 < sent_at < self.left_at:
            return None
        until = math.inf if valid_until <= 0.0 else valid_until
        if name != 'stand' and until <= now:
            return self._stand() if self.moving else None
        if name == self.running and self.moving:
            self.until = until
            return None
        self.running, self.until = name, until
        return name

    def due(self, now: float) -> str | None:
        """'stand' once a moving gait's deadline has passed (it is then standing), else None."""
        return self._stand() if self.moving and now >= self.until else None

    def left(self, now: float) -> None:
        """A command received at ``now`` (s, ROS time) makes the MCU leave the gait (leg
        targets, a burrow, an e-stop, a stop): the next gait command sent after it is sent
        whatever it is."""
        self.running, self.until, self.left_at = None, math.inf, now

    def _stand(self) -> str:
        self.running, self.until = 'stand', math.inf
        return 'stand'
