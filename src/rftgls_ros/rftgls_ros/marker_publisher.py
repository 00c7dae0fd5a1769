"""capacity_node's ``~/markers``: each estimate drawn for RViz and Foxglove, rate-limited.

visualization_msgs/MarkerArray, at most every marker_period_s: geometry from
rftgls_ros.capacity.markers (limit curve at My = 0, tether force, capacity coloured by margin,
slip direction, buried leg facets, the free surface, a text), in marker_frame_id.

Parameters (declared here): marker_period_s (s, 0 = no markers), marker_frame_id (the body
frame at the winch point p, the URDF's winch_link), marker_force_scale_m_per_N (m drawn per N).
The limit curve is sampled from a map predictor only (a live solver would need seconds for the
~90 tether angles); with a live predictor it is left out.
"""
from __future__ import annotations

import math
import time

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from rftgls_core.predictor.maps import MapPredictor
from rftgls_node_base.parameters import declare

from .capacity.estimator import Estimate
from .capacity.markers import CurveSample, MarkerStyle, estimate_markers, limit_curve

# name -> (default, description, lo, hi); start-up only (read-only: a run-time change is
# rejected by rclpy with its reason).
PARAMETERS = {
    'marker_period_s': (0.5, 'minimum time between two ~/markers', 0.0, 3600.0),
    'marker_frame_id': ('winch_link', 'frame of the markers', None, None),
    'marker_force_scale_m_per_N': (0.01, 'arrow length per newton', 0.0, 10.0),
}
KINDS = {'line_strip': Marker.LINE_STRIP, 'arrow': Marker.ARROW,
         'text': Marker.TEXT_VIEW_FACING, 'points': Marker.POINTS}


def marker_array(geoms, header: Header, lifetime_s: float) -> MarkerArray:
    """visualization_msgs markers of MarkerGeometry items; a DELETEALL first clears the
    markers of an earlier estimate that this one does not draw."""
    out = [Marker(header=header, action=Marker.DELETEALL)]
    life = Duration(sec=int(lifetime_s), nanosec=int((lifetime_s % 1.0) * 1e9))
    for i, g in enumerate(geoms):
        m = Marker(header=header, ns=g.ns, id=i, type=KINDS[g.kind], action=Marker.ADD,
                   lifetime=life, text=g.text, frame_locked=True)
        m.pose.orientation.w = 1.0
        m.color = ColorRGBA(r=g.rgba[0], g=g.rgba[1], b=g.rgba[2], a=g.rgba[3])
        if g.kind == 'arrow':   # shaft diameter, head diameter, head length
            m.scale.x, m.scale.y, m.scale.z = g.width_m, 2.5 * g.width_m, 4.0 * g.width_m
        elif g.kind == 'points':  # point width and height
            m.scale.x = m.scale.y = g.width_m
        elif g.kind == 'text':
            m.scale.z = g.width_m
            m.pose.position = Point(x=float(g.points[0, 0]), y=float(g.points[0, 1]),
                                    z=float(g.points[0, 2]))
        else:
            m.scale.x = g.width_m
        if g.kind != 'text':
            m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in g.points]
        out.append(m)
    return MarkerArray(markers=out)


class CapacityMarkers:
    """The ``~/markers`` publisher of a CapacityNode: its parameters, the rate limit, and the
    limit curve and buried facets cached per anchor state."""

    def __init__(self, node):
        self.node = node
        p = {name: declare(node, name, default, text, lo=lo, hi=hi)
             for name, (default, text, lo, hi) in PARAMETERS.items()}
        self.period_s = float(p['marker_period_s'])
        self.frame_id = p['marker_frame_id']
        self.style = MarkerStyle(force_scale_m_per_N=float(p['marker_force_scale_m_per_N']))
        self.pull = node.params['pull']
        self.pub_markers = node.create_publisher(MarkerArray, '~/markers', 2)
        pred = node.estimator.predictor
        primary = getattr(pred, 'primary', pred)     # FallbackPredictor: its map
        self.curve_map = primary if isinstance(primary, MapPredictor) else None
        self._curve_key: tuple | None = None
        self._curve: CurveSample | None = None
        self._robot = None
        self._buried_key: tuple | None = None
        self._buried = None
        self._last_markers = -math.inf

    def publish(self, est: Estimate, header: Header) -> None:
        """Draw `est` unless the last markers are younger than marker_period_s."""
        now = time.monotonic()
        if self.period_s <= 0.0 or now - self._last_markers < self.period_s:
            return
        self._last_markers = now
        st = est.state
        geoms = estimate_markers(
            est.word, st.theta_b if st else None, est.phi_rad, est.capacity_N,
            est.tension_N, est.margin_N, est.slip_twist, est.slipping, self.curve(est),
            self.style, st.h if st else None, self.buried(est))
        mheader = Header(stamp=header.stamp, frame_id=self.frame_id)
        self.pub_markers.publish(marker_array(geoms, mheader, 3.0 * self.period_s))

    def buried(self, est: Estimate):
        """Buried leg facet centroids relative to p, world axes (m), cached per state; None
        when the robot is unknown here."""
        if est.state is None:
            return None
        key = est.state.as_tuple()
        if key != self._buried_key:
            from rftgls_core.robots.presets import get_robot
            try:
                robot = self._robot = self._robot or get_robot(self.node.params['robot'])
            except (KeyError, ValueError):
                return None
            c = robot.pose(est.state, self.pull).facets.centroids
            self._buried = c[c[:, 2] < 0.0] - np.array([0.0, 0.0, est.state.h])
            self._buried_key = key
        return self._buried

    def curve(self, est: Estimate) -> CurveSample | None:
        """The limit curve at the estimate's state, from the map (cached per state)."""
        if self.curve_map is None or est.state is None:
            return None
        key = est.state.as_tuple()
        if key != self._curve_key:
            cmap, state, pull = self.curve_map, est.state, self.pull

            def capacity_at(phi: float) -> float | None:
                r = cmap.predict(state, phi, pull)
                return r.capacity_N if r.status.has_value else None

            self._curve = limit_curve(capacity_at, self.style.curve_phis_rad)
            self._curve_key = key
        return self._curve
