"""The project's messages around capacity_node, converted to and from the ROS-free types.

- AnchorEstimate (out, ``~/estimate``): one Estimate as a whole, NaN for every missing number,
  the status as a code and (deprecated, one release) as its word. The one message between
  capacity_node and its consumers: behavior_node reads nothing else of capacity_node.
- InputValue (in): a height or tether angle with its uncertainty band and its provenance
  (measured, modelled, assumed), so an estimate built on a value that is not a measurement
  says so (docs/design/capacity-inputs.md, "Provenance").
- ``add_estimate``: one estimate as a TugSeries sample (behavior_node's and teleop's tug plot);
  ``record_tug``: a consumer that records every estimate that way (teleop).

Field meanings and units: src/rftgls_interfaces/msg/*.msg.
"""
from __future__ import annotations

from geometry_msgs.msg import Twist
from std_msgs.msg import Header

from rftgls_core.types import Provenance, Status
from rftgls_interfaces.msg import AnchorEstimate, InputValue

from .behavior.tug_series import TugSeries
from .capacity.estimator import Estimate
from .capacity.inputs import band_problem

NAN = float('nan')
# Status word (Estimate.word: rftgls_core's Status words) -> code.
STATUS_CODES = {
    str(Status.OK): AnchorEstimate.STATUS_OK,
    str(Status.ASSUMED): AnchorEstimate.STATUS_ASSUMED,
    str(Status.STALE): AnchorEstimate.STATUS_STALE,
    str(Status.INVALID_INPUT): AnchorEstimate.STATUS_INVALID_INPUT,
    str(Status.OUT_OF_RANGE): AnchorEstimate.STATUS_OUT_OF_RANGE,
    str(Status.UNSUPPORTED): AnchorEstimate.STATUS_UNSUPPORTED,
    str(Status.DEGENERATE): AnchorEstimate.STATUS_DEGENERATE,
}
STATUS_OF_CODE = {code: word for word, code in STATUS_CODES.items()}
PROVENANCE_CODES = {Provenance.MEASURED: InputValue.MEASURED,
                    Provenance.MODELLED: InputValue.MODELLED,
                    Provenance.ASSUMED: InputValue.ASSUMED}
PROVENANCE_OF_CODE = {code: p for p, code in PROVENANCE_CODES.items()}


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
        header=header, status_code=STATUS_CODES[est.word], status=est.word,
        reason=est.reason, detail=est.detail,
        has_value=est.has_value, capacity_n=num_or_nan(est.capacity_N),
        capacity_lower_n=num_or_nan(est.capacity_lower_N), tension_n=num_or_nan(est.tension_N),
        margin_n=num_or_nan(est.margin_N), slipping=bool(est.slipping),
        slip_twist=twist_msg(est.slip_twist), phi_rad=num_or_nan(est.phi_rad),
        h_m=num_or_nan(st.h if st else None), theta_b_rad=num_or_nan(st.theta_b if st else None),
        theta_l1_rad=num_or_nan(st.theta_l1 if st else None),
        theta_l2_rad=num_or_nan(st.theta_l2 if st else None),
        assumed_inputs=list(est.assumed), modelled_inputs=list(est.modelled),
        measured_inputs=[n for n, p in est.provenance().items() if p == 'measured'],
        stale_inputs=list(est.stale),
        warnings=list(est.warnings), method=est.predictor, pull=pull)


def status_word(msg: AnchorEstimate) -> str:
    """The status word of an AnchorEstimate's status_code; 'unknown_<code>' for a code this
    node does not know (0: nobody filled it in), which no consumer takes as a value."""
    word = STATUS_OF_CODE.get(msg.status_code)
    return word if word is not None else f'unknown_{msg.status_code}'


def input_value(value: float, band: float, provenance: Provenance, source: str,
                header: Header) -> InputValue:
    """An InputValue message (SI value, half-width band or NaN, provenance, source text)."""
    return InputValue(header=header, value=float(value), band=float(band),
                      provenance=PROVENANCE_CODES[Provenance(provenance)], source=source)


def read_input_value(msg: InputValue) -> tuple[float, Provenance, float] | str:
    """(value, provenance, band) of an InputValue, or why it cannot be used (one line): an
    unknown provenance code (0: not stated) or a band that is neither >= 0 nor NaN."""
    provenance = PROVENANCE_OF_CODE.get(msg.provenance)
    if provenance is None:
        return (f'provenance code {msg.provenance} is none of measured '
                f'({InputValue.MEASURED}), modelled ({InputValue.MODELLED}), assumed '
                f'({InputValue.ASSUMED})')
    band = float(msg.band)
    why = band_problem(band)
    return why if why is not None else (float(msg.value), provenance, band)


def estimate_pose(msg: AnchorEstimate) -> tuple[float, float, float, float, float]:
    """(phi rad, h m, theta_B rad, theta_L1 rad, theta_L2 rad) an estimate was computed at."""
    return (msg.phi_rad, msg.h_m, msg.theta_b_rad, msg.theta_l1_rad, msg.theta_l2_rad)


def add_estimate(series: TugSeries, t: float, msg: AnchorEstimate, state: str) -> None:
    """One estimate into the tug time series, received at t (s, the recorder's clock) in
    behaviour state `state`: its tension, capacity and lower bound (N), status and pose."""
    series.add(t, msg.tension_n, msg.capacity_n, msg.capacity_lower_n, status_word(msg), state,
               estimate_pose(msg))


def record_tug(node, cap_ns: str, now, state) -> TugSeries:
    """Record every capacity_node estimate (``{cap_ns}/estimate``) for the tug time series
    (behavior/tug_series.py). now() -> s and state() -> str: the recording node's clock and
    its state at the estimate's arrival."""
    series = TugSeries()

    def on_estimate(msg: AnchorEstimate) -> None:
        add_estimate(series, now(), msg, state())

    node.create_subscription(AnchorEstimate, f'{cap_ns}/estimate', on_estimate, 10)
    return series
