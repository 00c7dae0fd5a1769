"""The simulated MiniRQuad: four leg servos, body pose, winch and sled, ground, power.

Sagittal model in the architecture's frames: world z up, surface z = 0; p (the winch point,
at the rear of the body) at (x_p, h); body pitch theta_b positive nose up; legs measured from
-z_B, positive forward.

Two bodies. With ``physics`` (a physics.PhysicsBody: ``--body physics``) the legs track the
MCU's references against the sand and the body moves as rftgls_core's whole-robot simulation
makes it; the pose, the torques and the power emerge. With ``physics_walk`` False
(``--body burrow-physics``) the physics rests while the robot walks, the walk is scripted as
below, and the physics body is put down where the walk left p once the legs stand after it
(a STAND; a burrow or leg command stands the robot up first and runs once the physics has
the body): burrows, tugs and slips emerge, the walk does not (`make demo` runs this body).
Without a physics body (minirquad_sim's default, what the behaviour tests run: faster and
repeatable; the physics' walk overturns the robot within two seconds,
docs/design/walk-burrow-physics.md) the body is scripted: walking at ``walk_speed``,
burrowing to Table II's mean pose, power from the calibrated ``PowerModel``, the anchor from
``ground``.

Geometry numbers the paper does not give are assumptions, named in ``Geometry``.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from minirquad_driver.protocol.messages import BurrowMode, Flag, GaitKind, Mode
from rftgls_conventions import G, tether_direction_xz
from rftgls_core.multibody.gaits import BURROW_DWELL
from rftgls_core.multibody.gaits import DEFAULT_BURROW_SPEED as BURROW_SPEED
from rftgls_core.predictor import Predictor
from rftgls_core.types import AnchorState

from .burrow import TABLE_II
from .gait import BuehlerClock, wrap_angle
from .gait_pose import GaitPoses
from .ground import default_ground, slip_per_m
from .ground_worker import BackgroundGround
from .physics import PhysicsBody
from .physics_worker import BackgroundPhysics
from .power import PowerModel
from .servo import Servo
from .winch import WinchSled

PROXIMAL = (0, 1)
# s: targets held this long are a gait's retracting pose (the host dwells BURROW_DWELL there)
DWELL_SEEN = 0.8 * BURROW_DWELL
DISTAL = (2, 3)
# rad/s: a leg turning slower than this holds its pose (an anchor), it does not stroke through
# the sand: it moves less than 0.03 deg in a 10 ms step, a thirtieth of the live ground's 1 deg
# grid. Above a firmware servo's smallest velocity step (0.229 rpm, 1.37 deg/s), which a leg
# creeps at for at most one encoder count (0.088 deg) as the firmware's hold settles it.
LEG_STILL_RAD_S = math.radians(3.0)
BODY_ORDER = (0, 2, 1, 3)   # servo index of each of the physics body's legs (physics.py)


@dataclass(frozen=True)
class Geometry:
    """axle_x: proximal and distal axle positions along x_B from p, m (wheelbase 0.090 m from
    the paper; the 0.03 m offset is an assumption); axle_z: axle height above p along z_B
    (assumption); leg_reach: hub-to-tip distance of the C-leg, m (0.09 m arc diameter);
    h_walk: height of p while walking and standing, m (assumption)."""

    axle_x: tuple[float, float] = (0.03, 0.12)
    axle_z: float = 0.02
    leg_reach: float = 0.09
    h_walk: float = 0.060
    walk_speed: float = 0.03      # m/s of body travel while walking (assumption)
    walk_leg_speed: float = 8.0   # servo speed limit in the air / walking, rad/s
    burrow_leg_speed: float = BURROW_SPEED  # servo slew while burrowing, rad/s (assumption)
    settle_time: float = BURROW_DWELL       # s held at the retracting pose (assumption)

    def tip_depth(self, leg: int, h: float, theta_b: float, theta_l: float) -> float:
        """Depth (m, >= 0) of a leg tip below the surface; straight hub-to-tip model."""
        ax = self.axle_x[0 if leg in PROXIMAL else 1]
        z_axle = h + ax * math.sin(theta_b) + self.axle_z * math.cos(theta_b)
        z_tip = z_axle - self.leg_reach * math.cos(theta_l + theta_b)
        return max(0.0, -z_tip)


# s a stand-up waits at a command's targets short of standing for the next one (a stream of
# leg commands sends one every 20 ms) before it goes on to standing
FOLLOW_WAIT_S = 0.2


@dataclass
class SimRobot:
    """State and one ``step(dt)`` of the simulated robot. Commands arrive as method calls."""

    #: rad: legs this close to their targets have arrived (the unburrow move's end)
    leg_arrived = 1e-3

    geometry: Geometry = field(default_factory=Geometry)
    ground: Predictor = field(default_factory=default_ground)   # the true sand
    pull: str = 'backward'      # C-leg orientation to the pull: the winch is on the back
    power_model: PowerModel = field(default_factory=PowerModel)
    winch: WinchSled = field(default_factory=WinchSled)
    mass: float = 0.296
    physics: PhysicsBody | BackgroundPhysics | None = None
    # False: the physics rests while walking (module doc)
    physics_walk: bool = True
    # Scripted body: where a burrow run leg by leg (SetLegs) settles (gait_pose.py); None:
    # SetLegs moves the legs only.
    gait_poses: GaitPoses | None = None

    def __post_init__(self) -> None:
        self.servos = [Servo(max_speed=self.geometry.walk_leg_speed) for _ in range(4)]
        self.leg_rates = [0.0] * 4
        self.x_p = 0.0
        self.h = self.geometry.h_walk
        self.theta_b = 0.0
        self.pitch_rate = 0.0
        self.mode = Mode.IDLE
        self.estop = False
        self.watchdog = False
        self.slipping = False
        self.time = 0.0
        self.clocks: list[BuehlerClock] | None = None
        self._gait_t0 = 0.0
        self._gait_offsets = [0.0] * 4
        self._burrow: str | None = None
        self._phase_t = 0.0
        self._body_from = (self.h, self.theta_b)
        self.power = self.power_model.p_idle
        self.last_prediction = None
        self._span = 0.0             # leg distance to go when the current burrow phase began
        self._reached_at: float | None = None   # phase time the retract pose was reached
        self._unburrowing = False
        self._rope = (0.0, 0.0)      # tension (N) and angle (rad) the tether last pulled with
        self._loaded = False         # the last step's rope loaded a settled anchor
        self._retract: tuple[float, float] | None = None   # most retracted leg targets (L1, L2)
        self._held: tuple[tuple[float, float], float] | None = None   # targets, since (s)
        self._dwelt: tuple[float, float] | None = None     # targets last held for a dwell
        self._leg_pose: tuple[float, float] | None = None  # (h, theta_b) a SetLegs burrow ends in
        self._physical = False       # the physics body moves the robot (not the script)
        self._stand_then_put_down = False
        self._stand_down = 0.0           # the leg angle a stand-up puts the body down at, rad
        self._followed_at = 0.0          # s: the stand-up last took a command's targets
        self._after_stand: Callable[[], None] | None = None   # the command a stand-up defers
        self._put_down()

    def _put_down(self) -> None:
        """Hand the body to the physics where the script left it: put down level, p at x_p,
        legs as they are, settled."""
        self._stand_then_put_down = False
        if self.physics is None or self._physical:
            return
        self.physics.place(self._to_body([s.angle for s in self.servos]), self.x_p)
        self.x_p, self.h, self.theta_b = self.physics.pose
        self._physical = True

    def _physics_has_body(self, then: Callable[[], None], legs=None, mask: int = 0x0F
                          ) -> bool:
        """True when the physics has the body (putting it down now if the legs stand), or
        there is none. Else the script stands the robot up first and runs `then` once the
        physics has it: the scripted walk leaves the legs anywhere in their swing (one leg
        pair at -22 deg, the other at 148 deg), and put down on those the robot cannot
        stand (the physics stops: no_rest). legs, mask: the leg targets of the command that
        waits (rad, servo order), which the stand-up follows where they lie short of
        standing (`_stand`)."""
        if self.physics is None or self._physical:
            # This command takes the legs: a stand-up under way (a walk's closing stand) ends
            # here, or it would send them back to standing once they rest at its targets.
            self._stand_then_put_down = False
            return True
        if all(abs(wrap_angle(s.angle)) < self.leg_arrived for s in self.servos):
            self._put_down()
            return True
        self._stand(0.0, legs, mask)
        self._after_stand = then
        return False

    def _stand(self, down: float, follow=None, mask: int = 0x0F) -> None:
        """Legs to `down` (rad) at walking speed; the physics takes the body once they are
        there. follow, mask: leg targets (servo order) the stand-up goes to instead where
        they lie between a leg and `down`: a stream of leg commands that brings the legs
        down to standing slower than the stand-up (the behaviour node's planned burrow
        ramps them at the burrow speed) is followed, not overtaken. Overtaken, the legs
        stood first, the physics took the body, and the next command, still on its way
        down, swung them forward through the sand again: a stroke the burrow's plan never
        simulated (in `make demo` each burrow's pitch then missed its replay by 2-5 deg)."""
        self._stand_then_put_down = not self._physical
        self._stand_down = down
        self._after_stand = None
        self.clocks = None
        self.mode = Mode.IDLE
        self._followed_at = self.time
        for i, s in enumerate(self.servos):
            s.max_speed = self.geometry.walk_leg_speed
            s.target = stand = _nearest(s.angle, down)
            if follow is not None and mask & (1 << i):
                t = _nearest(s.angle, follow[i])
                if min(s.angle, stand) <= t <= max(s.angle, stand):
                    s.target = t

    def _stand_on(self) -> None:
        """A followed command that stopped short of standing (one SET_LEGS to a pose between
        the legs and standing, not a stream down to it): after FOLLOW_WAIT_S at its targets
        with nothing newer, the stand-up goes on to standing."""
        if self.time - self._followed_at < FOLLOW_WAIT_S or any(
                abs(s.target - s.angle) >= self.leg_arrived for s in self.servos):
            return
        for s in self.servos:
            s.target = _nearest(s.angle, self._stand_down)

    def _lift(self) -> None:
        """Hand the body to the script for a walk (physics_walk False): the servos start from
        the legs the physics left."""
        if not self._physical or self.physics_walk:
            return
        assert self.physics is not None
        for s, a in zip(self.servos, self._from_body(list(self.physics.q))):
            s.angle = s.target = float(a)
        self._physical = False

    # ------------------------------------------------------------------ commands
    def set_legs(self, targets, mask: int = 0x0F) -> None:
        if not self._physics_has_body(lambda: self.set_legs(targets, mask), targets, mask):
            return
        self.mode = Mode.IDLE
        self.clocks = None
        for i, s in enumerate(self.servos):
            if mask & (1 << i):
                s.max_speed = self.geometry.walk_leg_speed
                s.target = _nearest(s.angle, targets[i])
        if self.gait_poses is not None and self.physics is None:
            self._leg_burrow()

    def _leg_burrow(self) -> None:
        """A burrow run leg by leg: the body settles, as the legs arrive, at the pose the
        gait map predicts for (most retracted legs, targets) (gait_pose.py)."""
        assert self.gait_poses is not None
        t = [wrap_angle(s.target) for s in self.servos]
        final = (0.5 * (t[0] + t[1]), 0.5 * (t[2] + t[3]))
        self._retract = final if self._retract is None else (
            min(self._retract[0], final[0]), min(self._retract[1], final[1]))
        if self._held is None or max(abs(a - b) for a, b in zip(self._held[0], final)) > 1e-4:
            if self._held is not None and self.time - self._held[1] >= DWELL_SEEN:
                self._dwelt = self._held[0]
            self._held = (final, self.time)
        # The retract pose: the one the legs dwelt at, else the most retracted since standing
        # (a walk can leave the legs further back than the gait's retract).
        self._leg_pose = None
        for retract in (self._dwelt, self._retract, final):
            if retract is not None and self._leg_pose is None:
                self._leg_pose = self.gait_poses.pose(retract, final)
        self._body_from = (self.h, self.theta_b)
        self._span = max(abs(s.target - s.angle) for s in self.servos)

    def set_gait(self, kind: int, period: float, duty: float, sweep: float, down: float,
                 phases, direction: int) -> None:
        self._retract = self._leg_pose = self._held = self._dwelt = None
        for s in self.servos:
            s.max_speed = self.geometry.walk_leg_speed
        if kind == GaitKind.STAND:
            # the script stands the robot up; the physics takes it once the legs are there
            self._stand(down)
            return
        self._after_stand = None
        self._stand_then_put_down = False     # a moving gait replaces a stand-up under way
        self._lift()
        self.clocks = [BuehlerClock(period, duty, sweep, down, ph, direction) for ph in phases]
        self._gait_t0 = self.time
        # Start each clock on the revolution nearest the leg so no leg spins a full turn.
        self._gait_offsets = [
            _nearest(s.angle, c.angle(0.0)) - c.angle(0.0)
            for s, c in zip(self.servos, self.clocks)]
        self.mode = Mode.WALKING
        self._body_from = (self.h, self.theta_b)
        self._phase_t = 0.0

    def burrow(self, mode: int) -> None:
        if not self._physics_has_body(lambda: self.burrow(mode)):
            return
        self.clocks = None
        self._retract = self._leg_pose = self._held = self._dwelt = None
        self._phase_t = 0.0
        self._body_from = (self.h, self.theta_b)
        for s in self.servos:
            s.max_speed = self.geometry.burrow_leg_speed
        if mode == BurrowMode.UNBURROW:
            self._burrow = None
            self.mode = Mode.IDLE
            self._aim((0.0, 0.0))
            self._unburrowing = True
            return
        self._burrow = BurrowMode(mode).name
        self.mode = Mode.BURROW_RETRACT
        self._aim(TABLE_II[self._burrow].retract)

    def set_winch(self, speed: float) -> None:
        self.winch.command = speed

    def set_estop(self, engage: bool) -> None:
        self.estop = engage
        if engage:
            self._stop_motion()

    def set_watchdog(self, tripped: bool) -> None:
        if tripped and not self.watchdog:
            self._stop_motion()
        self.watchdog = tripped

    def _stop_motion(self) -> None:
        # a stand-up stopped half-way is not a stance the physics could take the body in
        self._after_stand = None
        self._stand_then_put_down = False
        self.clocks = None
        self._burrow = None
        self._unburrowing = False
        if self.mode in (Mode.WALKING, Mode.BURROW_RETRACT, Mode.BURROW_FINAL):
            self.mode = Mode.IDLE
        for s in self.servos:
            s.hold()
        self.winch.command = 0.0

    def _aim(self, pose: tuple[float, float]) -> None:
        for i, s in enumerate(self.servos):
            s.target = _nearest(s.angle, pose[0] if i in PROXIMAL else pose[1])
        self._span = max(abs(s.target - s.angle) for s in self.servos)
        self._reached_at = None

    # ------------------------------------------------------------------ physics
    def leg_angles(self) -> list[float]:
        """Each leg's angle as its encoder reads it, rad in (-pi, pi] (PL, PR, DL, DR)."""
        if self._physical:
            assert self.physics is not None
            return [wrap_angle(a) for a in self._from_body(self.physics.q)]
        return [wrap_angle(s.angle) for s in self.servos]

    @staticmethod
    def _to_body(values) -> list[float]:
        """Servo order (PL, PR, DL, DR) -> the body's legs (left proximal, left distal, right
        proximal, right distal); the same swap maps back."""
        return [values[i] for i in BODY_ORDER]

    _from_body = _to_body

    def anchor_state(self) -> AnchorState:
        a = self.leg_angles()
        return AnchorState(self.h, self.theta_b, 0.5 * (a[0] + a[1]), 0.5 * (a[2] + a[3]))

    def depths(self) -> list[float]:
        return [self.geometry.tip_depth(i, self.h, self.theta_b, s.angle)
                for i, s in enumerate(self.servos)]

    def step(self, dt: float) -> None:
        if dt <= 0.0:
            return
        self.time += dt
        self._phase_t += dt
        theta_b0 = self.theta_b
        self._drive_legs()
        for s in self.servos:
            s.step(dt)
        if self._stand_then_put_down:
            self._stand_on()
        if self._stand_then_put_down and all(
                abs(wrap_angle(s.angle - self._stand_down)) < self.leg_arrived
                for s in self.servos):
            self._put_down()
            then, self._after_stand = self._after_stand, None
            if then is not None:
                then()
        if self._physical:
            self._step_physics(dt)
            self.pitch_rate = (self.theta_b - theta_b0) / dt
            return
        self._move_body(dt)
        self._resolve_rope(dt)
        self.pitch_rate = (self.theta_b - theta_b0) / dt
        legs = self.power_model.leg_power([s.velocity for s in self.servos], self.depths())
        winch = self.power_model.winch_power(self.winch.tension, self.winch.spool_velocity,
                                             self.winch.stalled)
        self.power = self.power_model.p_idle + legs + winch

    def _step_physics(self, dt: float) -> None:
        """The legs track the servos' references against the sand; the body, the rope and the
        power follow (module doc)."""
        body = self.physics
        assert body is not None
        x0 = self.x_p
        tension, phi = self._rope
        if self.estop or self.watchdog:
            tension = 0.0 if self.winch.command == 0.0 else tension
        mode = self.reported_mode().name.lower()
        if body.advance(dt, self._to_body([s.angle for s in self.servos]),
                        self._to_body([s.velocity for s in self.servos]),
                        self._to_body([s.target for s in self.servos]), tension, phi, mode):
            self.x_p, self.h, self.theta_b = body.pose
            self.leg_rates = self._from_body(list(body.rates))
        w = self.winch
        if self.estop or self.watchdog:
            w.command = 0.0
        w.reel(dt)
        dist, phi = w.geometry(self.x_p, self.h)
        demand = w.rope_k * max(0.0, dist - w.free_length())
        w.sled_moving = False
        if demand > w.sled_friction:
            # The sled slides toward p until the rope stretch matches its friction.
            excess = (demand - w.sled_friction) / w.rope_k
            dx, dz = self.x_p - w.sled_x, self.h - w.sled_z
            w.sled_x += excess * dx / max(math.hypot(dx, dz), 1e-9)
            demand = w.sled_friction
            w.sled_moving = True
        w.tension = demand
        self._rope = (demand, phi)
        if self._unburrowing and all(abs(s.target - s.angle) < 1e-3 for s in self.servos):
            self._unburrowing = False
        # the anchor gives way: p dragged toward the sled while the rope pulls
        self.slipping = demand > 0.0 and self.x_p - x0 < -1e-5
        winch = self.power_model.winch_power(w.tension, w.spool_velocity, w.stalled)
        self.power = self.power_model.p_idle + body.elec_W + winch

    def _drive_legs(self) -> None:
        if self.mode == Mode.WALKING and self.clocks:
            t = self.time - self._gait_t0
            for s, c, off in zip(self.servos, self.clocks, self._gait_offsets):
                s.target = c.angle(t) + off
        elif self.mode == Mode.BURROW_RETRACT and self._burrow:
            if all(abs(s.target - s.angle) < math.radians(0.5) for s in self.servos):
                if self._reached_at is None:
                    self._reached_at = self._phase_t
                if self._phase_t - self._reached_at >= self.geometry.settle_time:
                    self.mode = Mode.BURROW_FINAL
                    self._phase_t = 0.0
                    self._body_from = (self.h, self.theta_b)
                    self._aim(TABLE_II[self._burrow].final)
        elif self.mode == Mode.BURROW_FINAL and self._burrow:
            if all(abs(s.target - s.angle) < math.radians(0.5) for s in self.servos):
                self.mode = Mode.ANCHORED

    def _leg_progress(self) -> float:
        """Fraction of the current leg move completed (0..1), for the body's settling."""
        worst = max(abs(s.target - s.angle) for s in self.servos)
        if self._span < 1e-9:
            return 1.0
        return max(0.0, 1.0 - worst / self._span)

    def _move_body(self, dt: float) -> None:
        g = self.geometry
        if self.mode == Mode.WALKING:
            self.x_p += g.walk_speed * dt * self._walk_direction()
            self._relax(g.h_walk, 0.0, dt)
        elif self.mode in (Mode.BURROW_RETRACT, Mode.BURROW_FINAL) and self._burrow:
            seq = TABLE_II[self._burrow]
            h0, b0 = self._body_from
            if self.mode == Mode.BURROW_RETRACT:
                h1 = h0 + 0.6 * (seq.h - h0)
                b1 = 0.5 * seq.theta_b
            else:
                h1, b1 = seq.h, seq.theta_b
            k = self._leg_progress()
            self.h = h0 + (h1 - h0) * k
            self.theta_b = b0 + (b1 - b0) * k
        elif self.mode == Mode.IDLE and self._leg_pose is not None:
            (h0, b0), (h1, b1) = self._body_from, self._leg_pose
            # the legs arrived: within leg_arrived of their targets (below a servo's
            # resolution, 0.088 deg), however small the last command's span was
            arrived = all(abs(s.target - s.angle) < self.leg_arrived for s in self.servos)
            k = 1.0 if arrived else self._leg_progress()
            self.h = h0 + (h1 - h0) * k
            self.theta_b = b0 + (b1 - b0) * k
            if k > 1.0 - 1e-6:
                # Settled: from here on the body moves only as the ground makes it (a slip
                # under the tug turns and lifts it), as after a Table II burrow.
                self._leg_pose = None
        elif self._unburrowing:
            self._relax(g.h_walk, 0.0, dt)
            if abs(self.h - g.h_walk) < 1e-4 and all(abs(s.target - s.angle) < self.leg_arrived
                                                     for s in self.servos):
                self._unburrowing = False

    def _walk_direction(self) -> int:
        """+1 while the gait walks forward, -1 in reverse."""
        return self.clocks[0].direction if self.clocks else 1

    def _relax(self, h: float, theta_b: float, dt: float, rate: float = 2.0) -> None:
        a = min(1.0, rate * dt)
        self.h += (h - self.h) * a
        self.theta_b += (theta_b - self.theta_b) * a

    def _resolve_rope(self, dt: float) -> None:
        w = self.winch
        if self.estop or self.watchdog:
            w.command = 0.0
        w.reel(dt)
        dist, phi = w.geometry(self.x_p, self.h)
        demand = w.rope_k * max(0.0, dist - w.free_length())
        self.slipping = False
        w.sled_moving = False
        settled = self._anchor_settled()
        loading, self._loaded = self._loaded, False
        background = isinstance(self.ground, BackgroundGround)
        if demand <= 0.0:
            # A slack rope loads nothing: no need to ask the (live, costly) ground for an
            # answer now, only to have one solved by the time a tug loads the settled anchor.
            w.tension = 0.0
            if settled and background:
                self.ground.prefetch(self.anchor_state(), phi, self.pull)
            return
        friction = 0.4 * self.mass * G
        if not settled:
            # Legs in motion (a gait, a burrow, an unburrow, a stream of leg commands): no
            # settled anchor, the body drags on its friction. (This also keeps the live
            # ground's fits to settled poses, so the simulator stays real time.)
            self.last_prediction = None
            cap, slip = friction, _drag_twist(phi)
        else:
            # Loaded since the previous step, the anchor may meet its slip's newest answer
            # while the next is solved; newly loaded, its own (ground_worker.py).
            pred = self.ground.predict(self.anchor_state(), phi, self.pull, stand_in=loading) \
                if background else self.ground.predict(self.anchor_state(), phi, self.pull)
            self._loaded = True
            self.last_prediction = pred
            cap = pred.capacity_N if (pred.status.has_value and pred.capacity_N is not None) \
                else friction
            slip = slip_per_m(pred)
        if demand <= min(cap, w.sled_friction):
            w.tension = demand
        elif w.sled_friction <= cap:
            # The sled slides toward p until the rope stretch matches its friction.
            excess = (demand - w.sled_friction) / w.rope_k
            dx, dz = self.x_p - w.sled_x, self.h - w.sled_z
            w.sled_x += excess * dx / max(math.hypot(dx, dz), 1e-9)
            w.tension = w.sled_friction
            w.sled_moving = True
        else:
            # The anchor fails first: p slips along the predicted twist; the sled stays.
            vx, vz, wy = slip
            ux, uz = tether_direction_xz(phi)               # unit pull direction on p
            along = max(vx * ux + vz * uz, 0.2)
            s = (demand - cap) / w.rope_k / along
            self.x_p += vx * s
            self.h += vz * s
            self.theta_b -= wy * s   # wy about +y tilts the axle end down
            w.tension = cap
            self.slipping = True

    def _anchor_settled(self) -> bool:
        """The legs hold their pose and the body has settled on them: an anchor the sand
        holds (the ground answers for it), not legs dragging through the sand."""
        if self.mode in (Mode.WALKING, Mode.BURROW_RETRACT, Mode.BURROW_FINAL) \
                or self._unburrowing or self._leg_pose is not None:
            return False
        return all(abs(s.velocity) <= LEG_STILL_RAD_S for s in self.servos)

    def flags(self) -> int:
        f = 0
        if self.estop:
            f |= Flag.ESTOP
        if self.watchdog:
            f |= Flag.WATCHDOG_TRIPPED
        if self.winch.stalled:
            f |= Flag.WINCH_STALLED
        if self.slipping:
            f |= Flag.ANCHOR_SLIPPING
        if self.winch.sled_moving:
            f |= Flag.SLED_MOVING
        return f

    def reported_mode(self) -> Mode:
        if self.estop:
            return Mode.ESTOPPED
        if self.watchdog:
            return Mode.WATCHDOG
        return self.mode


def _drag_twist(phi: float) -> tuple[float, float, float]:
    """A body dragged along the tether: p moves along the pull, no rotation."""
    ux, _ = tether_direction_xz(phi)
    return (ux, 0.0, 0.0)


def _nearest(current: float, target: float) -> float:
    """The unwrapped equivalent of ``target`` nearest to ``current`` (shortest path)."""
    return current + wrap_angle(target - current)

