"""capacity_node's whole estimate as a message: rftgls_interfaces/AnchorEstimate from an
Estimate (rftgls_ros.capacity), with NaN for every missing number.

The one message between capacity_node and its consumers (behavior_node reads nothing else).
Field meanings and units: src/rftgls_interfaces/msg/AnchorEstimate.msg.
"""
from __future__ import annotations

from geometry_msgs.msg import Twist
from std_msgs.msg import Header

from rftgls_interfaces.msg import AnchorEstimate

from .capacity.estimator import Estimate

NAN = float('nan')


def num_or_nan(x: float | None) -> float:
    """A message float: NaN for None ("no value")."""
    return NAN if x is None else float(x)


def twist_msg(v: tuple[float, float, float] | None) -> Twist:
    """A planar twist (vx, vz, wy) as geometry_msgs/Twist (linear.x, linear.z, angular.y);
    NaN in all three for None."""
    t = Twist()
    vx, vz, wy = (NAN, NAN, NAN) if v is None else v
    t.linear.x, t.linear.z, t.angular.y = float(vx), float(vz), float(wy)
    return t


def estimate_msg(est: Estimate, header: Header, pull: str) -> AnchorEstimate:
    """The AnchorEstimate of one Estimate (NaN for every missing number)."""
    st = est.state
    return AnchorEstimate(
        header=header, status=str(est.status), reason=est.reason, detail=est.detail,
        has_value=est.has_value, capacity_n=num_or_nan(est.capacity_N),
        capacity_lower_n=num_or_nan(est.capacity_lower_N), tension_n=num_or_nan(est.tension_N),
        margin_n=num_or_nan(est.margin_N), slipping=bool(est.slipping),
        slip_twist=twist_msg(est.slip_twist), phi_rad=num_or_nan(est.phi_rad),
        h_m=num_or_nan(st.h if st else None), theta_b_rad=num_or_nan(st.theta_b if st else None),
        theta_l1_rad=num_or_nan(st.theta_l1 if st else None),
        theta_l2_rad=num_or_nan(st.theta_l2 if st else None),
        assumed_inputs=list(est.assumed), stale_inputs=list(est.stale),
        warnings=list(est.warnings), method=est.predictor, pull=pull)
