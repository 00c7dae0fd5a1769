"""One lab pull test as a rosbag2 (rosbags; sqlite3 or mcap): topics, types, frames, metadata.

The layout is documented for people in src/rftgls_ros/lab_README.md; this module is its single
source of truth (TOPICS). Topic names match capacity_node's inputs, so a replayed bag feeds the
node with at most two parameters changed (pitch_topic, phi_topic).

Frames:
    lab_world      the lab world W of docs/design/architecture.md: z up, free sand surface z = 0,
                   x horizontal in the sagittal plane pointing from p toward the axles (the
                   tether pulls p toward -x when phi = 0), y = z x x.
    camera_optical OpenCV camera frame (x right, y down, z forward), m.
    aruco markers  x = world x, y = world z, z = world -y (the printed face looks at a camera
                   on the -y side); see planar.py.

Times: bag log time = sample time (ns since the epoch, `t0_ns` + t); header stamps equal the
log time. All values SI.

Metadata: a JSON document (PullTestMeta.to_json) written once, at t0, on /lab/metadata
(std_msgs/String; replay publishes it reliable + transient-local so late joiners get it). The
topic is canonical because it survives every storage plugin and replay; the same JSON is
mirrored in metadata.yaml custom_data[CUSTOM_KEY] for tools that only list bags.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from rftgls_conventions import (
    LEG_JOINT_NAMES,
    LEG_KEYS,
    axle_angles,
    leg_keys_from_joint_names,
    one_line,
    tether_direction_xz,
    tether_phi_from_xz,
)
from rftgls_conventions.safe_read import load_json, parse_json
from rftgls_conventions.safe_write import atomic_write
from rftgls_core.geometry.transforms import matrix_to_quat
from rftgls_core.types import AnchorState

from . import planar
from .bag_files import BagError, guard_bag_read

SCHEMA = 'rftgls_lab.pull_test'
SCHEMA_VERSION = 1
CUSTOM_KEY = 'rftgls_lab.metadata'
JOINT_NAMES = LEG_JOINT_NAMES
WORLD_FRAME = 'lab_world'
CAMERA_FRAME = 'camera_optical'
MARKERS = ('tank', 'robot')

# topic -> (type, content). Every topic is optional except the metadata.
TOPICS: dict[str, tuple[str, str]] = {
    '/lab/metadata': ('std_msgs/msg/String', 'PullTestMeta JSON, once at t0'),
    '/tf_static': ('tf2_msgs/msg/TFMessage',
                   'fixed frames, once at t0: lab_world -> aruco_tank (the metadata\'s '
                   'tank_in_world) and lab_world -> camera_optical (from the first frame that '
                   'tracked the tank marker; tracked bags only)'),
    '/joint_states': ('sensor_msgs/msg/JointState',
                      'leg angles, rad from -z_B about the axles: ' + ', '.join(JOINT_NAMES)),
    '/winch/tension': ('geometry_msgs/msg/WrenchStamped',
                       'load cell: force of the tether on the robot at p, N, in lab_world '
                       '(= T d(phi) = (-T cos phi, 0, T sin phi)); torque 0'),
    '/winch/phi': ('std_msgs/msg/Float64', 'tether angle phi, rad (0 horizontal, <0 down)'),
    '/winch/height': ('std_msgs/msg/Float64', 'h = z of p from tracking, m (tracked frames only)'),
    '/lab/theta_b': ('std_msgs/msg/Float64', 'thetaB from tracking, rad (tracked frames only)'),
    '/lab/p_pose': ('geometry_msgs/msg/PoseStamped',
                    'winch point p in lab_world: position (x, 0, z), orientation = thetaB '
                    'about -y (tracked frames only)'),
    '/lab/aruco/tank': ('geometry_msgs/msg/PoseStamped', 'tank marker in camera_optical'),
    '/lab/aruco/robot': ('geometry_msgs/msg/PoseStamped', 'robot marker in camera_optical'),
    '/lab/tracking': ('diagnostic_msgs/msg/DiagnosticArray',
                      'per camera frame: one status per marker (aruco/tank, aruco/robot), '
                      'OK "tracked" or ERROR "lost"; values reprojection_px, out_of_plane_m'),
    '/lab/camera/image/compressed': ('sensor_msgs/msg/CompressedImage',
                                     'optional camera frames, png (mono8)'),
}


# Every message type a lab tool will read or replay: a bag's connection names its type as
# text, and only these texts are ever resolved (to rosbags' typestore or an rclpy message
# module). Anything else in a bag is skipped or refused, never imported.
KNOWN_TYPES: frozenset[str] = frozenset(t for t, _ in TOPICS.values())
# Offered QoS recorded per topic (metadata.yaml offered_qos_profiles), so a player replays
# latched topics as latched: the metadata and /tf_static reliable + transient-local depth 1
# (what a static transform broadcaster offers), everything else reliable, volatile, depth 100.
LATCHED_TOPICS = ('/lab/metadata', '/tf_static')
TANK_FRAME = 'aruco_tank'


def offered_qos(topic: str) -> list:
    """The rosbags QoS profile list recorded for a topic of the layout."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )
    latched = topic in LATCHED_TOPICS
    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, 1 if latched else 100, QosReliability.RELIABLE,
                QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
                zero, zero, QosLiveliness.AUTOMATIC, zero, False)]


def _typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def _check_types(path, connections) -> None:
    """BagError when a topic of the layout has another type than TOPICS says."""
    for c in connections:
        want = TOPICS.get(c.topic, (None,))[0]
        if want is not None and c.msgtype != want:
            raise BagError(f'{path}: topic {c.topic} has type {c.msgtype!r}, the lab layout '
                           f'says {want!r}')


@dataclass(frozen=True)
class MarkerSetup:
    """The ArUco markers of the bench and where p sits relative to them.

    tank_in_world: pose (x_m, z_m, theta_rad) of the tank marker's centre in lab_world; its
        z is the marker's height above the sand surface, so tracked z of p is h directly.
    p_in_robot: pose of the body frame at p (x along x_B) in the robot marker frame.
    Lengths are the printed black squares, m (measure them with calipers).
    """

    dictionary: str = 'DICT_4X4_50'
    tank_id: int = 0
    tank_length_m: float = 0.05
    robot_id: int = 7
    robot_length_m: float = 0.04
    tank_in_world: tuple[float, float, float] = (0.0, 0.0, 0.0)
    p_in_robot: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class CameraCalibration:
    """Pinhole camera: K (3x3, px) and OpenCV distortion coefficients."""

    width: int
    height: int
    K: tuple[tuple[float, float, float], ...]
    dist: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def simple(cls, width: int, height: int, f_px: float) -> 'CameraCalibration':
        """Square pixels, principal point at the image centre, no distortion."""
        cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
        return cls(width, height, ((f_px, 0.0, cx), (0.0, f_px, cy), (0.0, 0.0, 1.0)))

    @property
    def K_array(self) -> np.ndarray:
        return np.asarray(self.K, float)

    @property
    def dist_array(self) -> np.ndarray:
        return np.asarray(self.dist, float)

    @classmethod
    def load(cls, path: str | Path) -> 'CameraCalibration':
        """JSON {width, height, K: 3x3, dist: [...]} (the same keys this class writes);
        ValueError (one line) for anything else."""
        d = load_json(path, 'calibration', 'camera calibration')
        try:
            cam = cls(int(d['width']), int(d['height']),
                      tuple(tuple(map(float, r)) for r in d['K']),
                      tuple(map(float, d.get('dist', (0.0,) * 5))))
            ok = (cam.K_array.shape == (3, 3) and np.all(np.isfinite(cam.K_array))
                  and np.all(np.isfinite(cam.dist_array)) and 0 < cam.width <= 100_000
                  and 0 < cam.height <= 100_000)
        except (KeyError, TypeError, ValueError, AttributeError):
            ok = False
        if not ok:
            raise ValueError(f'{path}: not a camera calibration (want width, height, K: 3x3 '
                             'finite numbers, dist)')
        return cam


@dataclass(frozen=True)
class PullTestMeta:
    """What was tested. Angles rad, lengths m (JSON keys carry the units)."""

    test_id: str
    robot: str
    medium: dict                   # Medium.to_dict(): name, xi_n, mu_surf, zeta, ...
    pull: str                      # 'forward' | 'backward'
    initial_state: AnchorState     # as set up before the pull (h, thetaB, thetaL1, thetaL2)
    phi_rad: float = 0.0           # nominal tether angle
    synthetic: bool = False
    generator: str = ''            # the command that made a synthetic bag
    markers: MarkerSetup = field(default_factory=MarkerSetup)
    camera: CameraCalibration | None = None
    notes: str = ''
    truth_medium: dict | None = None  # synthetic bags only: the medium that generated them

    def to_json(self) -> str:
        s = self.initial_state
        d = {'schema': SCHEMA, 'schema_version': SCHEMA_VERSION, 'test_id': self.test_id,
             'robot': self.robot, 'medium': self.medium, 'pull': self.pull,
             'initial_state': {'h_m': s.h, 'theta_b_rad': s.theta_b,
                               'theta_l1_rad': s.theta_l1, 'theta_l2_rad': s.theta_l2},
             'phi_rad': self.phi_rad, 'synthetic': self.synthetic, 'generator': self.generator,
             'markers': asdict(self.markers),
             'camera': asdict(self.camera) if self.camera else None, 'notes': self.notes,
             'truth_medium': self.truth_medium}
        return json.dumps(d, allow_nan=False, sort_keys=True)

    @classmethod
    def from_json(cls, text: str, source: object = 'metadata') -> 'PullTestMeta':
        """The metadata of a JSON text; ValueError (one line) for anything that is not a
        pull-test metadata document of this schema (a field missing or of the wrong type)."""
        d = parse_json(text, source)
        try:
            return cls._from_dict(d)
        except (KeyError, TypeError, AttributeError, IndexError) as exc:
            raise ValueError(f'{source}: not a {SCHEMA} document ({type(exc).__name__}: '
                             f'{one_line(exc)})') from None

    @classmethod
    def _from_dict(cls, d) -> 'PullTestMeta':
        if not isinstance(d, dict):
            raise TypeError(f'a JSON object, got {type(d).__name__}')
        if d.get('schema') != SCHEMA or int(d.get('schema_version', -1)) > SCHEMA_VERSION:
            raise ValueError(f'not a {SCHEMA} v<={SCHEMA_VERSION} document: '
                             f'{d.get("schema")!r} v{d.get("schema_version")!r}')
        s = d['initial_state']
        m = d.get('markers') or {}
        m = MarkerSetup(**{**m, 'tank_in_world': tuple(m.get('tank_in_world', (0, 0, 0))),
                           'p_in_robot': tuple(m.get('p_in_robot', (0, 0, 0)))})
        cam = d.get('camera')
        cam = CameraCalibration(int(cam['width']), int(cam['height']),
                                tuple(tuple(r) for r in cam['K']),
                                tuple(cam['dist'])) if cam else None
        return cls(test_id=d['test_id'], robot=d['robot'], medium=d['medium'], pull=d['pull'],
                   initial_state=AnchorState(s['h_m'], s['theta_b_rad'], s['theta_l1_rad'],
                                             s['theta_l2_rad']),
                   phi_rad=float(d.get('phi_rad', 0.0)), synthetic=bool(d.get('synthetic')),
                   generator=d.get('generator', ''), markers=m, camera=cam,
                   notes=d.get('notes', ''), truth_medium=d.get('truth_medium'))


@dataclass
class Tracking:
    """Per camera frame quality (F frames). ok[:, 0] tank marker, ok[:, 1] robot marker.

    reprojection_px: RMS corner reprojection error per marker (NaN when lost);
    out_of_plane_m: robot marker's offset from the tank marker's plane (NaN when lost).
    marker_poses: per marker (F, 4, 4) camera_optical <- marker transforms, NaN when lost.
    """

    t: np.ndarray
    ok: np.ndarray
    reprojection_px: np.ndarray
    out_of_plane_m: np.ndarray
    marker_poses: dict[str, np.ndarray] | None = None

    def lost_times(self) -> dict[str, np.ndarray]:
        """Times (s) of the frames where each marker, or the pose of p, was not measured."""
        out = {name: self.t[~self.ok[:, i]] for i, name in enumerate(MARKERS)}
        out['p'] = self.t[~self.ok.all(axis=1)]
        return out


@dataclass
class PullTest:
    """One pull test in SI. Times t are seconds after t0_ns.

    force_t, tension_N, phi_rad: load cell samples (N,).
    pose_t, pose: tracked p in lab_world (M, 3) = (x_m, z_m, thetaB_rad); gaps stay gaps.
    joint_t, legs: (J,), (J, 2) = (thetaL1, thetaL2) rad (left/right averaged on reading).
    """

    meta: PullTestMeta
    t0_ns: int
    force_t: np.ndarray
    tension_N: np.ndarray
    phi_rad: np.ndarray
    pose_t: np.ndarray
    pose: np.ndarray
    joint_t: np.ndarray
    legs: np.ndarray
    tracking: Tracking | None = None
    images: list[tuple[float, bytes]] | None = None


def _stamp(ts, t_ns: int):
    return ts.types['builtin_interfaces/msg/Time'](sec=int(t_ns // 10**9),
                                                   nanosec=int(t_ns % 10**9))


def write_pull_test(path: str | Path, test: PullTest, storage: str = 'mcap') -> Path:
    """Write a rosbag2 directory (storage 'mcap' or 'sqlite3'); the directory must not exist
    (a symlink there is replaced, never followed: safe_write.atomic_write)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}[storage]
    ts = _typestore()
    T = ts.types
    path = Path(path)
    meta_json = test.meta.to_json()
    events: list[tuple[int, str, object]] = []   # (t_ns, topic, message), sorted on writing

    def tns(t: float) -> int:
        return test.t0_ns + int(round(float(t) * 1e9))

    def header(t_ns: int, frame: str):
        return T['std_msgs/msg/Header'](stamp=_stamp(ts, t_ns), frame_id=frame)

    V3, Q = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Quaternion']
    F64 = T['std_msgs/msg/Float64']
    events.append((test.t0_ns, '/lab/metadata', T['std_msgs/msg/String'](data=meta_json)))
    for t, f, phi in zip(test.force_t, test.tension_N, test.phi_rad):
        k = tns(t)
        dx, dz = tether_direction_xz(phi)
        force = V3(x=f * dx, y=0.0, z=f * dz)
        events.append((k, '/winch/tension', T['geometry_msgs/msg/WrenchStamped'](
            header=header(k, WORLD_FRAME),
            wrench=T['geometry_msgs/msg/Wrench'](force=force, torque=V3(x=0.0, y=0.0, z=0.0)))))
        events.append((k, '/winch/phi', F64(data=float(phi))))
    quats = planar.quaternion_from_theta(test.pose[:, 2]) if len(test.pose) else []
    for t, (x, z, tb), q in zip(test.pose_t, test.pose, quats):
        k = tns(t)
        events.append((k, '/lab/p_pose', T['geometry_msgs/msg/PoseStamped'](
            header=header(k, WORLD_FRAME), pose=T['geometry_msgs/msg/Pose'](
                position=T['geometry_msgs/msg/Point'](x=float(x), y=0.0, z=float(z)),
                orientation=Q(x=q[0], y=q[1], z=q[2], w=q[3])))))
        events.append((k, '/winch/height', F64(data=float(z))))
        events.append((k, '/lab/theta_b', F64(data=float(tb))))
    for t, (l1, l2) in zip(test.joint_t, test.legs):
        k = tns(t)
        events.append((k, '/joint_states', T['sensor_msgs/msg/JointState'](
            header=header(k, 'base_link'), name=list(JOINT_NAMES),
            position=np.array([l1, l1, l2, l2], float),
            # Empty velocity/effort are legal; rosbags serialises them exactly
            # (docs/design/ros2-from-pip.md).
            velocity=np.array([], float), effort=np.array([], float))))
    if test.tracking is not None:
        events += _tracking_events(ts, test.tracking, tns, header)
    for t, png in test.images or ():
        k = tns(t)
        events.append((k, '/lab/camera/image/compressed', T['sensor_msgs/msg/CompressedImage'](
            header=header(k, CAMERA_FRAME), format='png',
            data=np.frombuffer(png, dtype=np.uint8))))

    tf_static = _tf_static(ts, test, header(test.t0_ns, WORLD_FRAME))
    if tf_static is not None:
        events.append((test.t0_ns, '/tf_static', tf_static))
    events.sort(key=lambda e: e[0])  # stable: metadata stays first at t0
    with atomic_write(path, folder=True) as tmp, \
            Writer(tmp, version=8, storage_plugin=plugin) as w:
        w.set_custom_data(CUSTOM_KEY, meta_json)
        conns = {}
        for topic in dict.fromkeys(e[1] for e in events):
            conns[topic] = w.add_connection(topic, TOPICS[topic][0], typestore=ts,
                                            offered_qos_profiles=offered_qos(topic))
        for k, topic, msg in events:
            w.write(conns[topic], k, ts.serialize_cdr(msg, TOPICS[topic][0]))
    return path


def static_transforms(test: PullTest) -> list[tuple[str, str, np.ndarray]]:
    """(parent, child, 4x4 parent <- child) of the bench's fixed frames: the tank marker in
    lab_world (metadata tank_in_world (x, z, theta); marker axes x = world x rotated by theta
    about -y, y = world z likewise, z = world -y), and, when the bag has marker poses, the
    camera from the first frame that saw the tank marker: T_world_cam = T_world_tank
    inv(T_cam_tank)."""
    x, z, th = test.meta.markers.tank_in_world
    c, s = math.cos(th), math.sin(th)
    T_wt = np.eye(4)
    T_wt[:3, 0], T_wt[:3, 1], T_wt[:3, 2] = [c, 0.0, s], [-s, 0.0, c], [0.0, -1.0, 0.0]
    T_wt[:3, 3] = [x, 0.0, z]
    out = [(WORLD_FRAME, TANK_FRAME, T_wt)]
    tr = test.tracking
    poses = (tr.marker_poses or {}).get('tank') if tr is not None else None
    if poses is not None:
        seen = [i for i in range(len(poses)) if tr.ok[i, 0] and np.isfinite(poses[i]).all()]
        if seen:
            out.append((WORLD_FRAME, CAMERA_FRAME, T_wt @ np.linalg.inv(poses[seen[0]])))
    return out


def _tf_static(ts, test: PullTest, header):
    T = ts.types
    transforms = []
    for parent, child, M in static_transforms(test):
        q = matrix_to_quat(M[:3, :3])
        transforms.append(T['geometry_msgs/msg/TransformStamped'](
            header=T['std_msgs/msg/Header'](stamp=header.stamp, frame_id=parent),
            child_frame_id=child, transform=T['geometry_msgs/msg/Transform'](
                translation=T['geometry_msgs/msg/Vector3'](
                    x=float(M[0, 3]), y=float(M[1, 3]), z=float(M[2, 3])),
                rotation=T['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2], w=q[3]))))
    return T['tf2_msgs/msg/TFMessage'](transforms=transforms) if transforms else None


def _tracking_events(ts, tr: Tracking, tns, header) -> list:
    T = ts.types
    DS, KV = T['diagnostic_msgs/msg/DiagnosticStatus'], T['diagnostic_msgs/msg/KeyValue']
    out = []
    for i, t in enumerate(tr.t):
        k = tns(t)
        statuses = []
        for j, name in enumerate(MARKERS):
            ok = bool(tr.ok[i, j])
            values = [KV(key='reprojection_px', value=f'{tr.reprojection_px[i, j]:.4g}')]
            if name == 'robot':
                values.append(KV(key='out_of_plane_m', value=f'{tr.out_of_plane_m[i]:.6g}'))
            statuses.append(DS(level=DS.OK if ok else DS.ERROR, name=f'aruco/{name}',
                               message='tracked' if ok else 'lost', hardware_id='camera',
                               values=values))
            poses = (tr.marker_poses or {}).get(name)
            if ok and poses is not None:
                out.append((k, f'/lab/aruco/{name}',
                            _pose_msg(ts, poses[i], header(k, CAMERA_FRAME))))
        out.append((k, '/lab/tracking', T['diagnostic_msgs/msg/DiagnosticArray'](
            header=header(k, CAMERA_FRAME), status=statuses)))
    return out


def _pose_msg(ts, M: np.ndarray, hdr):
    T = ts.types
    q = matrix_to_quat(M[:3, :3])
    return T['geometry_msgs/msg/PoseStamped'](header=hdr, pose=T['geometry_msgs/msg/Pose'](
        position=T['geometry_msgs/msg/Point'](x=float(M[0, 3]), y=float(M[1, 3]),
                                              z=float(M[2, 3])),
        orientation=T['geometry_msgs/msg/Quaternion'](x=q[0], y=q[1], z=q[2], w=q[3])))


def _matrix_from_pose(pose) -> np.ndarray:
    x, y, z, w = pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w
    M = np.eye(4)
    M[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    M[:3, 3] = pose.position.x, pose.position.y, pose.position.z
    return M


def read_metadata(path: str | Path) -> PullTestMeta:
    """Only the metadata (first message of /lab/metadata). BagError on any problem."""
    return guard_bag_read(path, lambda: _read_metadata(path))


def _read_metadata(path) -> PullTestMeta:
    from rosbags.rosbag2 import Reader
    ts = _typestore()
    with Reader(path) as r:
        conns = [c for c in r.connections if c.topic == '/lab/metadata']
        _check_types(path, conns)
        # rosbags reads every connection when given none: no metadata topic, no reading.
        for c, _, raw in (r.messages(connections=conns) if conns else ()):
            return PullTestMeta.from_json(ts.deserialize_cdr(raw, c.msgtype).data)
    raise BagError(f'{path}: no /lab/metadata message; not a lab pull-test bag')


def read_pull_test(path: str | Path, images: bool = False) -> PullTest:
    """Read a bag written by write_pull_test (or by a recorder following TOPICS).
    BagError (one line) when the bag is missing, unreadable or not a lab pull test."""
    return guard_bag_read(path, lambda: _read_pull_test(path, images))


def _read_pull_test(path, images: bool) -> PullTest:
    from rosbags.rosbag2 import Reader

    ts = _typestore()
    meta = None
    t0_ns = None
    force, pose, joints, diag = [], [], [], []
    aruco: dict[str, dict[int, np.ndarray]] = {m: {} for m in MARKERS}
    imgs: list[tuple[int, bytes]] = []
    with Reader(path) as r:
        wanted = [c for c in r.connections if c.topic in TOPICS
                  and (images or c.topic != '/lab/camera/image/compressed')]
        _check_types(path, wanted)
        for c, k, raw in r.messages(connections=wanted):
            if c.topic == '/lab/camera/image/compressed':
                imgs.append((k, bytes(ts.deserialize_cdr(raw, c.msgtype).data)))
                continue
            if c.topic in ('/winch/phi', '/winch/height', '/lab/theta_b'):
                continue  # duplicates of /winch/tension and /lab/p_pose, kept for capacity_node
            msg = ts.deserialize_cdr(raw, c.msgtype)
            if c.topic == '/lab/metadata':
                if meta is None:
                    meta, t0_ns = PullTestMeta.from_json(msg.data), k
            elif c.topic == '/winch/tension':
                f = msg.wrench.force
                force.append((k, math.sqrt(f.x * f.x + f.y * f.y + f.z * f.z),
                              tether_phi_from_xz(f.x, f.z)))
            elif c.topic == '/lab/p_pose':
                o = msg.pose.orientation
                pose.append((k, msg.pose.position.x, msg.pose.position.z,
                             float(planar.theta_from_quaternion(np.array([o.x, o.y, o.z, o.w])))))
            elif c.topic == '/joint_states':
                keys = leg_keys_from_joint_names(msg.name)
                legs = {keys[n]: v for n, v in zip(msg.name, msg.position) if n in keys}
                if len(legs) < len(LEG_KEYS):
                    continue  # other joints only
                # left/right agreement is the analysis' concern (the raw legs are not kept)
                axles = axle_angles(legs, math.pi)
                joints.append((k, axles.theta_l1, axles.theta_l2))
            elif c.topic == '/lab/tracking':
                diag.append((k, msg))
            elif c.topic.startswith('/lab/aruco/'):
                aruco[c.topic.rsplit('/', 1)[1]][k] = _matrix_from_pose(msg.pose)
    if meta is None:
        raise BagError(f'{path}: no /lab/metadata message; not a lab pull-test bag')

    def sec(k):
        return (np.asarray(k, dtype=np.int64) - t0_ns) * 1e-9

    def cols(rows, n):
        a = np.array(rows, dtype=object).reshape(-1, n) if rows else np.zeros((0, n), object)
        return sec(a[:, 0].astype(np.int64)), a[:, 1:].astype(float)

    ft, fv = cols(force, 3)
    pt, pv = cols(pose, 4)
    jt, jv = cols(joints, 3)
    tracking = _read_tracking(diag, aruco, sec) if diag else None
    return PullTest(meta=meta, t0_ns=int(t0_ns), force_t=ft, tension_N=fv[:, 0],
                    phi_rad=fv[:, 1], pose_t=pt, pose=pv, joint_t=jt, legs=jv,
                    tracking=tracking,
                    images=[(float(sec(k)), b) for k, b in imgs] if images else None)


def _read_tracking(diag, aruco, sec) -> Tracking:
    n = len(diag)
    ok = np.zeros((n, 2), bool)
    rep = np.full((n, 2), np.nan)
    oop = np.full(n, np.nan)
    poses = {m: np.full((n, 4, 4), np.nan) for m in MARKERS}
    for i, (k, arr) in enumerate(diag):
        for st in arr.status:
            name = st.name.split('/', 1)[-1]
            if name not in MARKERS:
                continue
            j = MARKERS.index(name)
            ok[i, j] = st.level == 0
            vals = {kv.key: kv.value for kv in st.values}
            rep[i, j] = float(vals.get('reprojection_px', 'nan'))
            if name == 'robot':
                oop[i] = float(vals.get('out_of_plane_m', 'nan'))
            if k in aruco[name]:
                poses[name][i] = aruco[name][k]
    return Tracking(t=sec([k for k, _ in diag]), ok=ok, reprojection_px=rep, out_of_plane_m=oop,
                    marker_poses=poses)
