"""capacity_node's parameters without ROS: names (the unit in the name), defaults, ranges,
which ones take effect at run time, and their validation into plain config objects.

`configs(params)` turns a name -> value mapping (what the node declared, or a proposed change)
into an EstimatorConfig and a NodeConfig, or raises ConfigError with one line saying why. The
node declares every parameter with a descriptor built from PARAMETERS; a runtime change of a
RUNTIME parameter is validated here and applied, every other parameter is read-only after
start-up (rclpy rejects a change with its reason).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from rftgls_conventions import LEG_JOINT_NAMES, LEG_KEYS
from rftgls_node_base.parameters import ConfigError

from .estimator import DEFAULT_TIMEOUTS_S, EstimatorConfig
from .inputs import IMU_ROLL_LIMIT_RAD, IMU_TILT_LIMIT_RAD, LEG_LIMIT_RAD
from .node_predictor import DEFAULT_MAP

TRIGGERS = ('joint_states', 'pitch', 'tension', 'height', 'phi')
TENSION_AXES = ('x', 'y', 'z', 'tether')
FRESHNESS_SOURCES = ('header_stamp', 'receipt_time')


@dataclass(frozen=True)
class Param:
    """default (its type is the parameter type), description, and an optional static range
    [lo, hi] in the parameter's unit (ROS enforces it on every set)."""

    default: Any
    description: str
    lo: float | None = None
    hi: float | None = None


_TIMEOUT = 'age after which the {} input is stale, s'
PARAMETERS: dict[str, Param] = {
    # predictor (start-up only: the map is loaded and checked once)
    'map_file': Param(DEFAULT_MAP, "HDF5 capacity map; '' = live computation with live_method"),
    'live_method': Param('direct-warm', 'live solver when map_file is empty (direct-warm: '
                         "the cold direct's answers, warm-started per message)"),
    'live_n_twists': Param(0, 'twists of the live solver; 0 = DEFAULT_TWISTS (1000, rftgls_core'
                           '.surfaces.registry) for every surface method, direct included; '
                           'direct-warm keeps its own (400)', 0, 10**6),
    'out_of_range_live_method': Param('', "live solver answering off-grid states; '' = none"),
    'edge_live_method': Param('direct-warm', "live solver re-answering the map's edge-margin "
                              "answers next to the support edge (its interpolated margin can "
                              "say 'holds' where the anchor holds nothing); '' = they stand"),
    'robot': Param('minirquad', 'robot preset (must match the map)'),
    'anchor_description_file': Param('', "anchor description YAML for the live solver (a map must "
                               "answer for it); '' = the robot preset"),
    'anchor_state_variables': Param('', "description variable -> estimate, 'NAME=ESTIMATE,...' "
                                    "(estimates h, theta_b, theta_l1, theta_l2); '' = the "
                                    "variables' own names"),
    'medium': Param('m90_sand', 'medium preset (must match the map)'),
    'pull': Param('backward', "C-leg orientation to the pull: 'forward' or 'backward'"),
    'warm_up_solvers': Param(True, 'answer two states with the live solvers at start-up, '
                             'so they are compiled before the first estimate (slow only on a '
                             "machine's first run)"),
    # input topics (relative names: namespaces and remapping apply)
    'joint_states_topic': Param('joint_states', 'sensor_msgs/JointState topic'),
    'imu_topic': Param('imu/data', 'sensor_msgs/Imu topic (REP-145; orientation -> theta_B)'),
    'pitch_topic': Param('', "std_msgs/Float64 theta_B in rad; replaces the IMU if set"),
    'tension_topic': Param('winch/tension', 'geometry_msgs/WrenchStamped tension topic'),
    'tension_component': Param('x', "signed tension: load cell axis 'x', 'y', 'z', or "
                                    "'tether' (a world force projected on d(phi))"),
    'height_topic': Param('winch/height', "std_msgs/Float64 h in m, a measurement (a sensor, "
                          "a recorded lab bag); '' = none"),
    'height_estimate_topic': Param('winch/height_estimate', "rftgls_interfaces/InputValue h in "
                                   "m with its band and provenance (measured, modelled, "
                                   "assumed); '' = none"),
    'phi_topic': Param('', "std_msgs/Float64 phi in rad; '' = phi_rad only"),
    **{f'joint_{k}': Param(name, f'JointState name of the {k.replace("_", " ")} leg')
       for k, name in zip(LEG_KEYS, LEG_JOINT_NAMES)},
    # fallbacks and limits (SI)
    'height_m': Param(0.03, 'assumed height of p above the sand until a height sample, m'),
    'phi_rad': Param(math.radians(-20.0), 'assumed tether angle until a phi sample, rad',
                     -math.pi / 2, math.pi / 2),
    'leg_tolerance_rad': Param(math.radians(5.0), 'largest left/right leg disagreement, rad',
                               0.0, math.pi),
    'h_min_m': Param(-0.05, 'lowest plausible height of p, m'),
    'h_max_m': Param(0.30, 'highest plausible height of p, m'),
    'tension_max_N': Param(200.0, 'largest plausible tension, N', 0.0, 1e6),
    'tension_deadband_N': Param(0.05, 'a reading down to -deadband counts as zero, N',
                                0.0, 1e3),
    'imu_tilt_limit_rad': Param(IMU_TILT_LIMIT_RAD, 'body up axis this far from vertical is '
                                'implausible, rad', 0.0, math.pi),
    'imu_roll_limit_rad': Param(IMU_ROLL_LIMIT_RAD, 'body roll beyond this is implausible for '
                                'the sagittal model (legs at different depths), rad',
                                0.0, math.pi),
    'leg_limit_rad': Param(LEG_LIMIT_RAD, 'largest raw leg angle magnitude, judged before '
                           'wrapping, rad', 0.0, 1e3),
    'imu_frame_id': Param('imu_link', 'the IMU messages\' header.frame_id (others: '
                          'invalid_input)'),
    'tension_frame_id': Param('winch_link', "the tension messages' header.frame_id (others: "
                              "invalid_input)"),
    'assumed_height_range_m': Param(0.01, 'half-width of the range an assumed height may '
                                    'really take, m', 0.0, 1.0),
    'assumed_phi_range_rad': Param(math.radians(10.0), 'half-width of the range an assumed phi '
                                   'may really take, rad', 0.0, math.pi),
    'lower_bound_level': Param(0.0, 'one-sided confidence of ~/capacity_lower; 0 = off',
                               0.0, 1.0),
    'h_sigma_m': Param(0.002, 'standard deviation of h for the lower bound, m', 0.0, 1.0),
    'theta_b_sigma_rad': Param(math.radians(1.0), 'standard deviation of theta_B for the lower '
                               'bound, rad', 0.0, math.pi),
    'lower_bound_phi_step_rad': Param(0.0, 'grid of tether angles the lower bound is taken on '
                                      '(the smaller of the two bracketing phi; each '
                                      'remembered); 0 = at the exact phi, rad', 0.0, 0.2),
    'lower_bound_theta_b_step_rad': Param(0.0, 'grid of body pitches the lower bound is taken '
                                          'on (the smaller over the two bracketing pitches; '
                                          'each remembered); 0 = at the exact pitch, rad',
                                          0.0, 0.05),
    'phi_resolution_rad': Param(0.0, 'the point estimate is solved at phi rounded to this '
                                '(the lower bound is not); 0 = exact, rad', 0.0, 0.02),
    'theta_b_resolution_rad': Param(0.0, 'the point estimate is solved at theta_B rounded to '
                                    'this (the lower bound is not); 0 = exact, rad',
                                    0.0, 0.02),
    'capacity_rel_sigma': Param(0.0, 'relative standard deviation of the capacity (e.g. '
                                'sigma(xi_n)/xi_n from rftgls calibrate)', 0.0, 10.0),
    # timing
    **{f'{name}_timeout_s': Param(t, _TIMEOUT.format(name), 0.0, 3600.0)
       for name, t in DEFAULT_TIMEOUTS_S.items()},
    'freshness_source': Param('header_stamp', "input age from 'header_stamp' or "
                              "'receipt_time' (bag replay only)"),
    'clock_offset_tolerance_s': Param(0.05, 'stamps up to this far in the future are accepted,'
                                      ' s', 0.0, 60.0),
    'publish_rate_hz': Param(20.0, 'minimum output rate (heartbeat), Hz', 0.0, 1000.0),
    'trigger_inputs': Param(['tension'], 'inputs whose every message produces an output'),
    'input_queue_depth': Param(50, 'messages each input subscription keeps while the node is '
                               'busy (best effort, keep last): a burst up to this long is '
                               'answered in full, a longer one loses its oldest', 1, 10000),
    'trigger_max_queue_s': Param(0.01, 'a trigger message that waited longer than this in its '
                                 'queue is applied but answered only if no newer one comes '
                                 'within this time (the node is behind: the newest sample is '
                                 'answered); 0 = answer every trigger, s', 0.0, 10.0),
    'diagnostics_period_s': Param(1.0, 'period of unchanged /diagnostics, s', 0.0, 3600.0),
    'frame_id': Param('anchor', 'frame of the outputs (world-aligned axes at p)'),
}
DEFAULTS = {name: p.default for name, p in PARAMETERS.items()}

# Parameters a running node applies (validated first); every other one is start-up only.
RUNTIME = frozenset({
    'height_m', 'phi_rad', 'leg_tolerance_rad', 'h_min_m', 'h_max_m', 'tension_max_N',
    'tension_deadband_N', 'imu_tilt_limit_rad', 'imu_roll_limit_rad', 'leg_limit_rad',
    'assumed_height_range_m',
    'assumed_phi_range_rad', 'lower_bound_level', 'h_sigma_m', 'theta_b_sigma_rad',
    'capacity_rel_sigma', 'lower_bound_phi_step_rad', 'lower_bound_theta_b_step_rad',
    'phi_resolution_rad', 'theta_b_resolution_rad', 'clock_offset_tolerance_s',
    'diagnostics_period_s',
    *(f'{name}_timeout_s' for name in DEFAULT_TIMEOUTS_S),
})


@dataclass(frozen=True)
class NodeConfig:
    """The node's own settings (the estimator's are in EstimatorConfig). Validated by check()."""

    tension_component: str = 'x'
    freshness_source: str = 'header_stamp'
    imu_tilt_limit_rad: float = IMU_TILT_LIMIT_RAD
    imu_roll_limit_rad: float = IMU_ROLL_LIMIT_RAD
    imu_frame_id: str = 'imu_link'
    tension_frame_id: str = 'winch_link'
    triggers: frozenset[str] = frozenset({'tension'})
    publish_rate_hz: float = 20.0
    diagnostics_period_s: float = 1.0
    trigger_max_queue_s: float = 0.01

    def check(self) -> NodeConfig:
        """Raise ConfigError on the first bad value; return self."""
        if self.tension_component not in TENSION_AXES:
            # 'norm' (|force|) was removed: it turned a -5 N reading into +5 N.
            raise ConfigError(f"tension_component must be the load cell axis 'x', 'y' or 'z', "
                              f"or 'tether' (all signed), got {self.tension_component!r}")
        if self.freshness_source not in FRESHNESS_SOURCES:
            raise ConfigError(f'freshness_source must be one of {", ".join(FRESHNESS_SOURCES)}'
                              f', got {self.freshness_source!r}')
        tilt = self.imu_tilt_limit_rad
        if not (math.isfinite(tilt) and 0.0 < tilt < math.pi):
            raise ConfigError(f'imu_tilt_limit_rad must lie in (0, pi), got {tilt!r}')
        roll = self.imu_roll_limit_rad
        if not (math.isfinite(roll) and 0.0 < roll < math.pi / 2):
            raise ConfigError(f'imu_roll_limit_rad must lie in (0, pi/2), got {roll!r}')
        if not self.triggers <= set(TRIGGERS):
            raise ConfigError(f'trigger_inputs must be a subset of {list(TRIGGERS)}, '
                              f'got {sorted(self.triggers)}')
        for name in ('publish_rate_hz', 'diagnostics_period_s'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f'{name} must be > 0, got {v!r}')
        q = self.trigger_max_queue_s
        if not (math.isfinite(q) and q >= 0):
            raise ConfigError(f'trigger_max_queue_s must be >= 0, got {q!r}')
        return self


def configs(p: Mapping[str, Any]) -> tuple[EstimatorConfig, NodeConfig]:
    """(EstimatorConfig, NodeConfig) from parameter values, both checked (ConfigError)."""
    timeouts = {name: p[f'{name}_timeout_s'] for name in DEFAULT_TIMEOUTS_S}
    est = EstimatorConfig(
        pull=p['pull'], timeouts_s=timeouts, leg_tolerance_rad=p['leg_tolerance_rad'],
        height_m=p['height_m'], phi_rad=p['phi_rad'], h_range_m=(p['h_min_m'], p['h_max_m']),
        leg_limit_rad=p['leg_limit_rad'],
        tension_max_N=p['tension_max_N'], tension_deadband_N=p['tension_deadband_N'],
        clock_tolerance_s=p['clock_offset_tolerance_s'],
        assumed_height_range_m=p['assumed_height_range_m'],
        assumed_phi_range_rad=p['assumed_phi_range_rad'],
        lower_bound_level=p['lower_bound_level'],
        h_sigma_m=p['h_sigma_m'], theta_b_sigma_rad=p['theta_b_sigma_rad'],
        capacity_rel_sigma=p['capacity_rel_sigma'],
        lower_bound_phi_step_rad=p['lower_bound_phi_step_rad'],
        lower_bound_theta_b_step_rad=p['lower_bound_theta_b_step_rad'],
        phi_resolution_rad=p['phi_resolution_rad'],
        theta_b_resolution_rad=p['theta_b_resolution_rad']).check()
    node = NodeConfig(p['tension_component'], p['freshness_source'], p['imu_tilt_limit_rad'],
                      p['imu_roll_limit_rad'], p['imu_frame_id'], p['tension_frame_id'],
                      frozenset(p['trigger_inputs']), p['publish_rate_hz'],
                      p['diagnostics_period_s'], p['trigger_max_queue_s']).check()
    return est, node
