"""The reel's speed law, and what it asks of an anchor.

The tug reels at ``tug_speed_m_s`` while the tension stays below ``slow_ratio`` x the lower
bound; inside the slow band it slows linearly to ``min_speed_fraction`` of that speed at
``stop_ratio``, where the margin guard stops it. The sled slides at its own tension (the
need), so an anchor whose lower bound puts the need inside the slow band is reeled in at a
crawl for the whole tug, and a long tether then outlasts the tug timeout (HOLD, `tug_slow`,
and a re-burrow after the time is spent). ``tug_ratio`` turns that into the ratio a decision
judges by: the largest need / lower bound at which the reel still brings ``reel_m`` of
tether in within the timeout. Units: m, m/s, s; ratios are tension / capacity.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .config import BehaviorConfig


def reel_fraction(cfg: BehaviorConfig, ratio: float) -> float:
    """Reel speed as a fraction of tug_speed_m_s at tension / capacity ``ratio``: 1 below the
    slow band, falling linearly across it, never below min_speed_fraction (the guard, not
    the law, stops the reel at stop_ratio)."""
    band = max(cfg.stop_ratio - cfg.slow_ratio, 1e-6)
    return min(1.0, max(cfg.min_speed_fraction, (cfg.stop_ratio - ratio) / band))


def tug_ratio(cfg: BehaviorConfig, reel_m: float) -> float:
    """The largest steady tension / capacity ratio at which the reel brings ``reel_m`` (m) of
    tether in within tug_timeout_s: stop_ratio when even the slowest reel speed does it,
    else the ratio whose speed fraction covers reel_m in the timeout (slow_ratio when only
    full speed does, or not even that: a tether too long for any anchor is the timeout's to
    report, not the choice's)."""
    reach = cfg.tug_speed_m_s * cfg.tug_timeout_s
    needed = max(reel_m, 0.0) / reach if reach > 0.0 else 1.0
    if needed <= cfg.min_speed_fraction:
        return cfg.stop_ratio
    return cfg.stop_ratio - min(needed, 1.0) * (cfg.stop_ratio - cfg.slow_ratio)
