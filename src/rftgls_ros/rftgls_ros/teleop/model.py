"""Keys, guard and screen of the teleoperated tug, without ROS or a terminal.

Guard: a decision uses the lower bound, not the point estimate. Reeling in while tension >=
``limit_fraction`` x the estimate's lower bound needs a deliberate override (press ``!`` then
reel in within ``override_window`` s); the screen shows it in red. When the estimate is not
evidence (``behavior.evidence.judge``: status other than ``ok``, or ``assumed`` with an input
outside ``accept_assumed_inputs`` (default none), no finite value, no finite lower bound,
computed at another height than the one sent, or older than ``stale_after``), reeling in is
refused and a running reel-in is stopped; paying
out and stopping always work. ``extrapolated`` is never accepted. The height of p sent to
capacity_node and the pitch check of the burrow: anchor.py.
Screen: a number is shown only when it is one; capacity and lower bound that are not evidence
are greyed with the reason, the load percentage and the margin only when tension and lower
bound are both valid. Units: N, m/s (reel-in positive), s.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from rftgls_core.planning.burrowed import BurrowedPose

from ..behavior.evidence import judge
from ..tether import TetherTracker
from .anchor import AnchorTracker, HeightInput

RED, GREEN, YELLOW, BOLD, RESET = '\x1b[1;31m', '\x1b[32m', '\x1b[33m', '\x1b[1m', '\x1b[0m'
GREY = '\x1b[2m'   # faint: a number that is not evidence

KEYS = {
    'i': 'reel in faster', 'o': 'reel in slower / pay out', ' ': 'stop the winch',
    '1': 'burrow DH', '2': 'burrow DL', '3': 'burrow SH', 'u': 'unburrow', 'w': 'walk',
    's': 'stand', '!': 'arm override', 'x': 'STOP ALL (e-stop)', 'r': 'release e-stop',
    'q': 'quit',
}


@dataclass
class TeleopConfig:
    step: float = 0.01            # m/s per key press
    max_speed: float = 0.05       # m/s
    limit_fraction: float = 0.8   # of the lower bound, beyond which pulling needs the override
    override_window: float = 5.0  # s the override stays armed
    stale_after: float = 0.5      # s without a capacity output -> not valid
    rope_length: float = 0.50     # m, tether paid out at start (for phi)
    attach_height: float = 0.01   # m
    h_stand: float = 0.060        # m, height of p when not burrowed
    sled_mass: float = 0.4        # kg, the sled the robot burrows tied to (its gait map)
    accept_assumed_inputs: tuple[str, ...] = ()   # inputs an 'assumed' estimate may assume


def _load_words(r: float) -> str:
    """The guard's reason in words: tension / lower bound (r, not NaN; inf: lower bound 0)."""
    return (f'tension {100 * r:.0f} % of the lower bound' if math.isfinite(r)
            else 'lower bound 0 N, nothing to pull against')


class TeleopModel:
    """``key(ch, t)`` and ``update(t)`` return the commands to publish as (topic, value)."""

    def __init__(self, config: TeleopConfig | None = None,
                 poses: Mapping[str, BurrowedPose | str | None] | None = None):
        """poses: each mode's modelled burrowed pose, or why there is none."""
        self.cfg = config or TeleopConfig()
        self.winch = 0.0
        self.tension = math.nan
        self.capacity = math.nan          # point estimate, N (shown, never decided on)
        self.capacity_lower = math.nan    # its lower bound, N (what the guard uses; NaN: none)
        self.status = 'stale'
        self.t_capacity = -math.inf
        self.assumed_inputs: frozenset[str] | None = None
        self.modelled_inputs: frozenset[str] = frozenset()
        self.capacity_h = math.nan        # height of p the estimate was computed at, m
        self.height_measured = False      # capacity_node measured that height itself
        self.slip_twist = (math.nan, math.nan, math.nan)
        self.anchor = AnchorTracker(poses or {}, self.cfg.h_stand)
        self.override_until = -math.inf
        self.estop = False
        # Command topics nobody subscribes to (the robot's bridge is not up or not yet
        # discovered): a key press would be lost, so the screen says so. None = not known.
        self.unheard: tuple[str, ...] | None = None
        self.message = 'press a key; q quits'
        self.alert = False
        self.quit = False
        self.tether = TetherTracker(self.cfg.rope_length, self.cfg.attach_height)
        self.t = 0.0

    # ------------------------------------------------------------------ state
    def verdict(self):
        """behavior.evidence.judge on the last estimate: usable, reason code, detail."""
        # Any non-finite lower bound is "none" (judge's default inf would leave it out).
        lower = self.capacity_lower if math.isfinite(self.capacity_lower) else math.nan
        return judge(self.t, self.capacity, self.status, self.t_capacity, self.cfg.stale_after,
                     self.assumed_inputs, frozenset(self.cfg.accept_assumed_inputs), lower,
                     self.capacity_h, None if self.height_measured else self.height().value)

    def valid(self) -> bool:
        return self.verdict().usable

    def ratio(self) -> float:
        """tension / lower bound; NaN unless both are valid (never shown as a number then);
        inf on a lower bound of 0 N (nothing to pull against: the guard holds)."""
        if not self.valid() or not math.isfinite(self.tension):
            return math.nan
        if self.capacity_lower <= 0.0:
            return math.inf
        return self.tension / self.capacity_lower

    def reel_in_valid_until(self) -> float:
        """When the evidence under the running reel-in runs out (s, this model's clock): the
        estimate's sample time plus ``stale_after``, sent with the set-point so the MCU brakes
        then even if this process stalls; 0 (no limit of its own) when not reeling in."""
        return self.t_capacity + self.cfg.stale_after if self.winch > 0.0 else 0.0

    def overridden(self) -> bool:
        return self.t < self.override_until

    @property
    def mode(self) -> str | None:
        return self.anchor.mode

    def height(self) -> HeightInput:
        """The height of p sent to capacity_node (anchor.py)."""
        return self.anchor.height()

    # ------------------------------------------------------------------ inputs
    def key(self, ch: str, t: float) -> list[tuple[str, object]]:
        self.t = t
        out: list[tuple[str, object]] = []
        if ch == 'q':
            self.quit = True
            self.winch = 0.0
            return [('winch', 0.0)]
        if ch == 'x':
            self.estop, self.winch = True, 0.0
            self.message, self.alert = 'STOP ALL: e-stop engaged, winch braked (r releases)', True
            return [('winch', 0.0), ('estop', True)]
        if ch == 'r':
            self.estop, self.alert = False, False
            self.message = 'e-stop released'
            return [('estop', False)]
        if ch == ' ':
            self.winch = 0.0
            self.message, self.alert = 'winch stopped', False
            return [('winch', 0.0)]
        if ch == '!':
            self.override_until = t + self.cfg.override_window
            self.message, self.alert = (f'OVERRIDE armed for {self.cfg.override_window:.0f} s: '
                                        'reel in past the limit at your own risk'), True
            return []
        if ch in '123':
            self.anchor.burrow('DH DL SH'.split()[int(ch) - 1])
            self.winch = 0.0
            self.message, self.alert = f'burrow {self.mode} requested', False
            return [('winch', 0.0), ('burrow', self.mode)]
        if ch == 'u':
            self.anchor.burrow(None)
            self.message, self.alert = 'unburrow requested', False
            return [('burrow', 'UNBURROW')]
        if ch in 'ws':
            self.anchor.burrow(None)
            gait = 'walk' if ch == 'w' else 'stand'
            self.message, self.alert = f'gait {gait}', False
            return [('gait', gait)]
        if ch == 'o':
            self.winch = max(-self.cfg.max_speed, self.winch - self.cfg.step)
            self.message, self.alert = f'winch {1e3 * self.winch:+.0f} mm/s', False
            return [('winch', self.winch)]
        if ch == 'i':
            if self.estop:
                self.message, self.alert = 'e-stop engaged: release with r first', True
                return out
            verdict = self.verdict()
            if not verdict.usable:
                self.message = (f'capacity status {self.status}: refusing to pull harder '
                                f'(no valid prediction: {verdict.detail})')
                self.alert = True
                return out
            r = self.ratio()
            if r >= self.cfg.limit_fraction and not self.overridden():
                limit = f' >= {100 * self.cfg.limit_fraction:.0f} %' if math.isfinite(r) else ''
                self.message = f'{_load_words(r)}{limit}: press ! then i to override'
                self.alert = True
                return out
            self.winch = min(self.cfg.max_speed, max(0.0, self.winch) + self.cfg.step)
            self.alert = self.overridden() and r >= self.cfg.limit_fraction
            self.message = f'winch {1e3 * self.winch:+.0f} mm/s' + (
                ' (OVERRIDE)' if self.alert else '')
            return [('winch', self.winch)]
        return out

    def update(self, t: float) -> list[tuple[str, object]]:
        """Apply the guard to the current reel-in; call on every new input."""
        self.t = t
        if self.winch <= 0.0:
            return []
        if not self.valid():
            self.winch = 0.0
            self.message, self.alert = (f'capacity status {self.status}: winch stopped, '
                                        'refusing to pull'), True
            return [('winch', 0.0)]
        r = self.ratio()
        if r >= self.cfg.limit_fraction and not self.overridden():
            self.winch = 0.0
            self.message = (f'{_load_words(r)}: winch stopped; '
                            'press ! then i to override')
            self.alert = True
            return [('winch', 0.0)]
        return []

    # ------------------------------------------------------------------ screen
    def screen(self) -> list[str]:
        """The lines of one redraw. No 'nan' anywhere: a missing number is '--', capacity and
        lower bound that are not evidence are greyed with the reason, the load (tension / lower
        bound) only from two valid numbers."""
        verdict = self.verdict()
        r = self.ratio()
        limit = self.cfg.limit_fraction
        over = r >= limit     # False for NaN
        color = RED if over or not verdict.usable else GREEN
        f = lambda x, u: f'{x:6.2f} {u}' if math.isfinite(x) else '   --  ' + u  # noqa: E731
        if verdict.usable:
            capacity = f(self.capacity, 'N')
            lower = f(self.capacity_lower, 'N')
            margin = f(self.capacity_lower - self.tension, 'N')
        else:
            capacity = f'{GREY}{f(self.capacity, "N")}{RESET}'
            lower = f'{GREY}{f(self.capacity_lower, "N")}{RESET}'
            margin = f(math.nan, 'N')
        width = 30
        fill = 0 if math.isnan(r) else max(0, min(width, round(r * width))) if math.isfinite(r) \
            else width
        bar = '#' * fill + '-' * (width - fill)
        mark = int(limit * width)
        bar = bar[:mark] + '|' + bar[mark:]
        if math.isfinite(r):
            load = f'{color}[{bar}] {100 * r:5.0f} %{RESET} of the lower bound'
        elif math.isinf(r):
            load = f'{RED}[{bar}]    -- %{RESET} of the lower bound (0 N: nothing to pull on)'
        else:
            why = ('tension not measured' if verdict.usable else 'no valid lower bound')
            load = f'{GREY}[{bar}]    -- %{RESET} of the lower bound ({why})'
        tw = self.slip_twist
        twist = ('holds (no slip predicted)' if all(math.isfinite(x) for x in tw)
                 and not any(tw) else
                 f'vx {tw[0]:+.2f} vz {tw[1]:+.2f} wy {tw[2]:+.2f} (unit direction)'
                 if all(math.isfinite(x) for x in tw) else '--')
        ov = f'{RED}OVERRIDE{RESET}' if self.overridden() else 'guarded'
        if self.unheard is None:
            robot = f'{GREY}robot link unknown{RESET}'
        elif self.unheard:
            robot = f'{RED}NOBODY LISTENS to {", ".join(self.unheard)}{RESET}'
        else:
            robot = 'robot listening'
        # The status line names what an estimate assumes, and what an ok rests on a model.
        assumed = (f' ({", ".join(sorted(self.assumed_inputs))})'
                   if self.status == 'assumed' and self.assumed_inputs else
                   f' ({", ".join(sorted(self.modelled_inputs))} modelled)'
                   if self.status == 'ok' and self.modelled_inputs else '')
        evidence = ('prediction usable' if verdict.usable
                    else f'{GREY}not usable: {verdict.detail}{RESET}')
        lines = [
            f'{BOLD}MiniRQuad teleop tug{RESET}  i/o reel in/out  space stop  1/2/3 burrow '
            'DH/DL/SH  u unburrow  w/s walk/stand  ! override  x STOP ALL  r release  q quit',
            f'tension  {f(self.tension, "N")}   capacity {capacity}   lower bound {lower}'
            f'   margin {margin}   status {color}{self.status}{assumed}{RESET}',
            f'load     {load} (limit {100 * limit:.0f} %)',
            f'evidence {evidence}',
            f'slip twist {twist}',
            self.anchor.line(),
            *([f'{RED}PITCH CHECK FAILED: {self.anchor.flag}{RESET}'] if self.anchor.flag
              else []),
            f'winch {1e3 * self.winch:+5.0f} mm/s   {ov}   '
            f'tether {self.tether.free_length:.3f} m   {robot}'
            + (f'   {RED}E-STOP{RESET}' if self.estop else ''),
            (RED if self.alert else YELLOW) + self.message + RESET,
        ]
        return lines
