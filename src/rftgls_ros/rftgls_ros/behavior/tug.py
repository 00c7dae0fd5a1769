"""The tug (TUG): reel the sled in on live evidence, slow down and stop at the margin guard,
stop at a slip, and report how far the spool went after every safety stop.

Each step, in order: the sled arrived or the tug timed out; the slip detector (slip.py); the
evidence (machine.evidence, with the configured own-map fallback while capacity_node is
silent); the capacity against the need (SHORT); the margin guard (GUARD); then the reel speed.
A tug never outlives its evidence: the winch is set to 0 in the step that sees it gone
(docs/design/tug-safety.md). Units: N, m, m/s, s, J.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from . import evidence
from .reel import reel_fraction
from .slip import SlipEvent
from .states import HoldCause, State

if TYPE_CHECKING:
    from .machine import BehaviorMachine


@dataclass(frozen=True)
class SpoolAt:
    """The spool encoder (m reeled since MCU boot; None before the first reading) at t (s)."""

    t: float
    spool: float | None


@dataclass(frozen=True)
class PendingStop:
    """A safety stop whose reel is still to be reported: counted from `start` (the last usable
    estimate, or the moment of the slip), for reason code `reason`; `since` names `start` in
    the report's text."""

    start: SpoolAt
    reason: str
    since: str


@dataclass
class TugAttempt:
    """One tug, from entering TUG to leaving it: when it started (s), the energy readings
    (t s, J) for the paper's last-8-s window, the sliding tensions (N), when the last live
    event went out, the evidence gap in progress and the last usable evidence, whether the
    own-map fallback was announced, and the tension/capacity ratio of the last reel-in (NaN
    before one)."""

    started_t: float
    good: SpoolAt
    energy: deque[tuple[float, float]] = field(default_factory=deque)
    tensions: list[float] = field(default_factory=list)
    last_live: float = -math.inf
    gap: SpoolAt | None = None
    gap_reason: str = ''
    fallback_warned: bool = False
    ratio: float = math.nan


class Tug:
    """TUG. The slip detector (the machine's ``slip``) keeps the anchor's references across
    attempts; only its tension-drop rule restarts with each attempt."""

    def __init__(self, machine: BehaviorMachine):
        self.m = machine
        self.attempt = TugAttempt(0.0, SpoolAt(0.0, None))
        self.pending_stop: PendingStop | None = None
        self.had_value = False      # capacity_node gave a value-carrying status this run
        self.on_enter = {State.TUG: self._enter_tug}
        self.on_step = {State.TUG: self._do_tug}

    def _enter_tug(self) -> None:
        o = self.m.obs
        self.attempt = TugAttempt(started_t=o.t, good=SpoolAt(o.t, o.spool))
        self.m.slip.settle(o.theta_b, o.legs)     # the anchor's first tug: before any load
        self.m.slip.new_pull()

    def _do_tug(self) -> None:
        """One tug step: end or slip first, then evidence, then the margin guard, then reel."""
        o = self.m.obs
        if o.energy is not None:
            self.attempt.energy.append((o.t, o.energy))
        if self._ended() or self._slipped():
            return
        got = self._evidence()
        if got is None:
            return
        capacity, source = got
        if self._short(capacity, source) or self._guard(capacity, source):
            return
        self._reel(capacity, source)

    def _ended(self) -> bool:
        """The sled arrived or the tug timed out (winch stopped, state changed)."""
        m, cfg = self.m, self.m.cfg
        if m.tether.free_length <= cfg.arrive_length_m:
            m.winch = 0.0
            self.finish('arrived')
            m.go(State.CYCLE_DONE, f'sled arrived ({m.tether.free_length:.3f} m of '
                                   'tether left)')
            return True
        if m.elapsed() > cfg.tug_timeout_s:
            m.winch = 0.0
            self.finish('timeout')
            ratio = self.attempt.ratio
            if ratio >= cfg.slow_ratio:
                # The sled's own sliding tension kept the reel inside the slow band: the
                # anchor holds, but too thinly to bring the sled in within the timeout. A
                # stronger burrow tugs at speed; only without one does the cycle stop.
                m.burrow.hold(HoldCause.SLOW, f'tug timeout ({cfg.tug_timeout_s:.0f} s) with '
                                              f'the tension at {100 * ratio:.0f} % of the '
                                              f'capacity, inside the slow band from '
                                              f'{100 * cfg.slow_ratio:.0f} %: winch stopped',
                              'tug_slow')
            else:
                m.stop_cycle(f'tug timeout ({cfg.tug_timeout_s:.0f} s)')
            return True
        return False

    def _slipped(self) -> bool:
        """The slip detector fired (see _on_slip)."""
        o = self.m.obs
        if not self.m.cfg.slip_detect:
            return False
        ev = self.m.slip.update(o.tension, o.spool, o.theta_b, o.legs)
        if ev is None:
            return False
        self.finish('slip')
        self._on_slip(ev)
        return True

    def anchor_slipped(self, when: str, legs: bool = True) -> bool:
        """Outside TUG (a re-check after a link gap or an evidence wait): has this anchor
        slipped, now seen against its references or recorded before? Then the slip policy
        answers (HOLD, re-burrow stronger or stop) and True; the winch stays stopped.
        legs False: the leg rule is left out (the legs left the burrowed pose otherwise)."""
        m = self.m
        if not m.cfg.slip_detect:
            return False
        done = m.slip.slipped
        if done is not None:
            m.winch = 0.0
            m.burrow.hold(HoldCause.SLIP, f'the {m.mode} anchor slipped ({done.reason}) '
                                          f'before {when}: winch stopped', done.reason)
            return True
        m.slip.held(m.obs.tension)    # a tension the host did not see may have been higher
        ev = m.slip.moved(m.obs.theta_b, m.obs.legs if legs else None, when)
        if ev is None:
            return False
        self._on_slip(ev)
        return True

    def _evidence(self) -> tuple[float, str] | None:
        """(capacity N scaled by the chooser's slip correction, its source), or None when
        there is no usable evidence (the winch is stopped by _evidence_gap)."""
        m, a = self.m, self.attempt
        cfg, o = m.cfg, m.obs
        v = m.evidence()
        capacity, source = o.capacity_lower, 'capacity_node lower bound'
        if not v.usable and cfg.own_capacity_fallback and self.had_value \
                and v.reason in (evidence.NO_ESTIMATE, evidence.TIMEOUT):
            # capacity_node went silent after a value: only then, and only when configured.
            cap, status = m.own_capacity()
            if cap is not None and status == 'ok':
                if not a.fallback_warned:
                    a.fallback_warned = True
                    m.event('warn', f'capacity_node silent ({v.detail}): using '
                                    f'behavior_node\'s own map prediction at the measured '
                                    f'pose and the Table II height (own_capacity_fallback)')
                capacity, source = cap, 'own map'
                v = evidence.Verdict(True, evidence.USABLE, False, 'own map')
        if not v.usable:
            self._evidence_gap(v)
            return None
        assert capacity is not None  # usable evidence carries a value (evidence.judge)
        if source != 'own map':
            self.had_value = True
        if a.gap is not None:
            # Evidence back before the encoder showed the spool standing: nothing to report.
            self.pending_stop = None
        a.gap = None
        a.good = SpoolAt(o.t, o.spool)
        return capacity * m.chooser.scale, source

    def _short(self, capacity: float, source: str) -> bool:
        """Capacity below what the tug needs (the guard would stop it before the sled moves):
        stop and hold (SHORT)."""
        m = self.m
        required = m.chooser.guard_required(m.need.value)
        if capacity >= required:
            return False
        m.winch = 0.0
        self.finish('short')
        m.burrow.hold(HoldCause.SHORT, f'capacity {capacity:.2f} N ({source}) below the '
                                       f'required {required:.2f} N: winch stopped',
                      'capacity_short')
        return True

    def _guard(self, capacity: float, source: str) -> bool:
        """Margin guard: tension at stop_ratio x capacity stops the winch before the slip."""
        m, cfg = self.m, self.m.cfg
        tension = m.obs.tension or 0.0
        ratio = tension / capacity if capacity > 0 else math.inf
        m.cycle.min_margin = min(m.cycle.min_margin, capacity - tension)
        if ratio < cfg.stop_ratio:
            return False
        m.winch = 0.0
        self.finish('guard stop')
        m.need.raise_floor(tension)
        m.burrow.hold(HoldCause.GUARD, f'margin guard: tension {tension:.2f} N >= '
                                       f'{cfg.stop_ratio:.2f} x capacity {capacity:.2f} N '
                                       f'({source}), winch stopped before the predicted slip '
                                       f'{self.twist_text()}', 'margin_guard')
        return True

    def _reel(self, capacity: float, source: str) -> None:
        """Reel in, slower inside the slow band; sample the sliding tension; a live event
        every live_period."""
        m, a = self.m, self.attempt
        cfg, o = m.cfg, m.obs
        tension = o.tension or 0.0
        ratio = tension / capacity if capacity > 0 else math.inf
        m.winch = cfg.tug_speed_m_s * reel_fraction(cfg, ratio)
        a.ratio = ratio
        # The reel-in may run until its estimate ages out (the MCU enforces it); the own-map
        # fallback has no estimate to age: the MCU's deadman alone.
        m.winch_valid_until = 0.0 if source == 'own map' \
            else o.t_capacity + cfg.estimate_timeout_s
        if m.taut() and o.spool_velocity > 0.5 * m.winch > 0:
            a.tensions.append(tension)
        if o.t - a.last_live >= cfg.live_period_s:
            a.last_live = o.t
            m.event('live', f'tug {m.mode}: T {tension:.2f} N, C {capacity:.2f} N '
                            f'({source}), margin {capacity - tension:+.2f} N '
                            f'({100 * (1 - ratio):.0f}'
                            f' %), phi {math.degrees(m.tether.phi(m.height)):.0f} deg,'
                            f' slip twist {self.twist_text()}, status '
                            f'{o.capacity_status}, reel {1e3 * m.winch:.0f} mm/s, '
                            f'tether {m.tether.free_length:.3f} m',
                    tension=tension, capacity=capacity, source=source)

    def _evidence_gap(self, v: evidence.Verdict) -> None:
        """No usable evidence in TUG: winch stopped now; abort now or after the grace time."""
        m, a = self.m, self.attempt
        o = m.obs
        m.winch = 0.0
        if a.gap is None:
            a.gap, a.gap_reason = SpoolAt(o.t, o.spool), v.reason
            self.pending_stop = PendingStop(a.good, v.reason, 'the last usable estimate')
            if m.cycle is not None and not m.cycle.reason:
                m.cycle.reason = v.reason      # the row says why its tug stopped, even briefly
            m.event('warn', f'tug evidence lost ({v.reason}: {v.detail}): winch stopped',
                    reason=v.reason)
        if not v.transient:
            m.retry.abort(v, in_tug=True)
        elif o.t - a.gap.t >= m.cfg.evidence_grace_s:
            # Recorded under what stopped the winch (a late 'stale' or no_value keeps its code
            # when the estimates then also age), with what is seen now as the detail.
            first = a.gap_reason or v.reason
            m.retry.abort(evidence.Verdict(False, first, True, v.detail), in_tug=True)

    def _on_slip(self, ev: SlipEvent) -> None:
        """The anchor moved under load: stop, attribute the slip to the anchor, learn how much
        weaker the ground is than predicted, then re-burrow into a mode that is strong enough
        with that correction (or stop: burrow.hold)."""
        m = self.m
        o = m.obs
        m.winch = 0.0
        m.slip.record(ev)
        if m.cycle is not None and not m.cycle.slip:
            m.cycle.slip = ev.reason       # the row keeps it whatever ends the cycle
        if m.state == State.TUG:
            self.pending_stop = PendingStop(SpoolAt(o.t, o.spool), ev.reason,
                                            'the slip was detected')
        predicted = o.capacity if (o.capacity is not None and math.isfinite(o.capacity)) \
            else m.own_capacity()[0]
        note = ''
        if predicted and predicted > 0 and ev.peak_tension > 0:
            k = min(1.0, ev.peak_tension / (predicted * m.chooser.scale)) * m.chooser.scale
            if k < m.chooser.scale:
                m.chooser.scale = k
                note = (f'; the anchor held {ev.peak_tension:.2f} N where {predicted:.2f} N was '
                        f'predicted: predictions scaled by {k:.2f} from now on')
        m.weakest = ev.peak_tension
        m.event('warn', f'anchor slip detected ({ev.reason}: {ev.detail}){note}',
                reason=ev.reason, peak_tension=ev.peak_tension, scale=m.chooser.scale,
                pitch_lost_rad=ev.pitch_lost, legs_moved_rad=ev.legs_moved)
        m.burrow.hold(HoldCause.SLIP, f'anchor slip ({ev.reason}): winch stopped', ev.reason)

    def twist_text(self) -> str:
        tw = self.m.obs.slip_twist
        if tw is None or not all(math.isfinite(x) for x in tw) or not any(tw):
            return '(holds: no slip predicted)'
        return f'(vx {tw[0]:+.2f}, vz {tw[1]:+.2f}, wy {tw[2]:+.2f})'

    def finish(self, outcome: str) -> None:
        """Book the attempt to the cycle (time, energy, sliding tensions); an arrived tug also
        updates the required force from its sliding tension."""
        m, a = self.m, self.attempt
        c, o = m.cycle, m.obs
        c.tug_s += o.t - a.started_t
        if a.energy:
            t_end, e_end = a.energy[-1]
            e_start = a.energy[0][1]
            win = [e for t, e in a.energy if t >= t_end - m.cfg.tug_energy_window_s]
            c.tug_total_j += e_end - e_start
            c.tug_j += e_end - (win[0] if win else e_end)
        c.tensions.extend(a.tensions)
        if outcome == 'arrived':
            med = m.need.update(a.tensions)
            if med is not None:
                m.event('info', f'measured sliding tension {med:.2f} N '
                                f'(nominal {m.need.nominal:.2f} N); required force now '
                                f'{m.need.value:.2f} N')

    def interrupted(self, reason: str = 'link_stale') -> None:
        """The link went (or became untrusted) during the tug: report the reel from the last
        usable evidence under ``reason``."""
        if self.pending_stop is None:
            self.pending_stop = PendingStop(self.attempt.good, reason,
                                            'the last usable estimate')

    def report_stop(self) -> None:
        """After a safety stop, report once how far the spool went after the last usable
        estimate (m) when the encoder shows it standing still: what the robot measured."""
        w, o = self.pending_stop, self.m.obs
        if w is None or o.spool is None or abs(o.spool_velocity) > 1e-6:
            return
        self.pending_stop = None
        t0, spool0 = w.start.t, w.start.spool
        reel = (o.spool - spool0) if spool0 is not None else float('nan')
        self.m.event('stop', f'winch standing after {w.reason}: {1e3 * reel:.1f} mm reeled in '
                             f'since {w.since} ({1e3 * (o.t - t0):.0f} ms before)',
                     reason=w.reason, reel_m=reel, since_s=o.t - t0)
