"""What the behaviour machine reads and returns each step: the Observation of the robot and of
capacity_node (SI values with their receipt times), and the Commands to publish."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from rftgls_core.types import Provenance


@dataclass
class Observation:
    """What the robot and capacity_node last said, with the times t_* (s, node clock) their
    samples were taken (behavior_node: by header stamp, never the receipt time).

    legs: (thetaL1, thetaL2) rad (left/right averaged); theta_b rad; tension N; spool m
    reeled since MCU boot and spool_velocity m/s (reel-in positive); energy J since bridge
    start; power W; link_ok from /minirquad/link (rftgls_interfaces/LinkState) and, when it
    is not ok, link_fault its reason code (link_stale, link_untrusted) and link_detail its
    text; capacity N along the tether, its lower bound capacity_lower N (what every decision
    uses; None or NaN: none published) and its status word from capacity_node;
    assumed_inputs the input names capacity_node reported as assumed (None = not received);
    capacity_h the height of p the estimate was computed at, m (NaN: not stated), and
    height_measured whether capacity_node measured that height itself (it then does not
    come from this node); slip_twist (vx, vz, wy) unit direction in the anchor frame;
    leg_samples every leg sample (t_legs, thetaL1, thetaL2) that arrived since the last step,
    oldest first (legs/t_legs is the newest): a step that runs late still sees each one, so a
    planned burrow's record for its replay has no gap where the node was busy.
    """

    t: float
    legs: tuple[float, float] | None = None
    t_legs: float = -math.inf
    theta_b: float | None = None
    tension: float | None = None
    t_tension: float = -math.inf
    spool: float | None = None
    spool_velocity: float = 0.0
    energy: float | None = None
    power: float | None = None
    link_ok: bool = False
    link_fault: str = 'link_stale'
    link_detail: str = 'link stale'
    capacity: float | None = None
    capacity_lower: float | None = None
    capacity_status: str = 'stale'
    t_capacity: float = -math.inf
    assumed_inputs: frozenset[str] | None = None
    capacity_h: float = math.nan
    height_measured: bool = False
    slip_twist: tuple[float, float, float] | None = None
    leg_samples: list[tuple[float, float, float]] = field(default_factory=list)


@dataclass
class Commands:
    """To publish after a step: one-shot ``gait``/``burrow`` commands (in order), the winch
    reel-in set-point (m/s, 0 brakes), h (m) and phi (rad) for capacity_node, and the events
    of this step (to log and publish, in order). h is never measured (MiniRQuad has no sensor
    for it): assumed (Table II, walking) or modelled (a planned gait's prediction),
    height_provenance; height_band is the half-width of its range (m, NaN = not stated) and
    height_source says where the number comes from. legs: the leg targets of a planned burrow
    this step (published on leg_targets), None otherwise. winch_valid_until: when the evidence
    a reel-in rests on runs out (s on the observation's clock: the estimate's sample time plus
    estimate_timeout_s; 0: no limit of its own), sent with the set-point so the MCU brakes then
    whatever the host does. walking: the machine wants the walk gait running this step (the
    node refreshes it, so the robot stands when the node stops)."""

    oneshots: list[tuple[str, str]]
    winch: float
    height: float
    phi: float
    events: list[dict] = field(default_factory=list)
    height_band: float = math.nan
    height_source: str = ''
    height_provenance: Provenance = Provenance.ASSUMED
    legs: tuple[float, float] | None = None   # leg targets (theta_L1, theta_L2), rad, or None
    winch_valid_until: float = 0.0
    walking: bool = False
