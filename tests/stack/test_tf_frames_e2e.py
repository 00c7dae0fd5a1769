"""Every frame_id the stack publishes resolves in its TF tree:
minirquad_sim on a pty, bridge_node, capacity_node and state_publisher as ``ros2 run``
processes, real DDS on this worker's domain. A probe discovers every topic those three nodes
publish, subscribes to each whose type carries a std_msgs/Header anywhere (MarkerArray's
markers, TFMessage's transforms included), collects messages, and checks with the ROS-free
resolver (rftgls_ros.tf_tree.TfTree) that every frame_id found reaches one root, odom,
through the transforms received on /tf and /tf_static.

Empty frame_ids are allowed only on types that are not spatial (JointState: positions of
named joints; BatteryState; DiagnosticArray; the driver's LinkState): REP-103/tf2 give them no
frame.
"""
from __future__ import annotations

import importlib
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('tf2_msgs')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import Header  # noqa: E402

from rftgls_ros.capacity.params import PARAMETERS  # noqa: E402
from rftgls_ros.marker_publisher import PARAMETERS as EXTRA_PARAMETERS  # noqa: E402
from rftgls_ros.tf_tree import TfTree, Transform  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
NODES = ('bridge_node', 'capacity_node', 'state_publisher')
NON_SPATIAL = {'sensor_msgs/msg/JointState', 'sensor_msgs/msg/BatteryState',
               'diagnostic_msgs/msg/DiagnosticArray', 'rftgls_interfaces/msg/LinkState'}
# Published once (and on change) as reliable + transient local: only such a subscriber gets them.
LATCHED = ('/tf_static', '/minirquad/link')
# What must be among the collected topics (a discovery that finds too little fails here).
MUST = {'/joint_states', '/imu/data', '/winch/tension', '/tf', '/tf_static',
        '/capacity_node/capacity', '/capacity_node/estimate', '/capacity_node/markers'}


def msg_class(type_name: str):
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


def has_header(cls, depth=0) -> bool:
    if cls is Header:
        return True
    if depth > 4 or not hasattr(cls, 'get_fields_and_field_types'):
        return False
    for t in cls.get_fields_and_field_types().values():
        base = t.split('<')[-1].rstrip('>').split('[')[0]
        if '/' in base and has_header(msg_class(base.replace('/', '/msg/', 1)), depth + 1):
            return True
    return False


def headers(msg):
    """frame_ids of a message: its own header's, TransformStamped's child_frame_id, and those
    of the messages in its sequences (MarkerArray.markers, TFMessage.transforms, ...).
    Headers of other nested fields are not followed: Marker.texture is an embedded image whose
    header means nothing without a texture (it stays empty on every marker)."""
    if not hasattr(msg, 'get_fields_and_field_types'):
        return
    for field in msg.get_fields_and_field_types():
        v = getattr(msg, field)
        if field == 'header':
            yield v.frame_id
        elif field == 'child_frame_id':
            yield v
        elif isinstance(v, list):
            for item in v:
                yield from headers(item)


def transforms(msg) -> list[Transform]:
    out = []
    for ts in msg.transforms:
        tr, r = ts.transform.translation, ts.transform.rotation
        out.append(Transform(ts.header.frame_id, ts.child_frame_id, (tr.x, tr.y, tr.z),
                             (r.x, r.y, r.z, r.w)))
    return out


def collect(ros_context, nodes, must, log_text=lambda: ''):
    """Subscribe to every topic `nodes` publish whose type carries a header, until each of
    `must` (and every other one found) has messages; returns (messages by topic, types)."""
    probe = rclpy.create_node('tf_probe', context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    got: dict[str, list] = {}
    types: dict[str, str] = {}
    static = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
    # Best effort + volatile matches every publisher (reliable or not, latched or not).
    any_qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)

    def discover():
        names = {n for n, _ns in probe.get_node_names_and_namespaces()}
        for node in nodes:
            if node not in names:
                continue
            for topic, (typ, *_rest) in probe.get_publisher_names_and_types_by_node(node, '/'):
                if topic in types:
                    continue
                types[topic] = typ
                cls = msg_class(typ)
                if has_header(cls):
                    got[topic] = []
                    probe.create_subscription(
                        cls, topic, got[topic].append, static if topic in LATCHED
                        else any_qos)

    def complete():
        return must <= set(got) and all(got.values()) and \
            {n for n, _ns in probe.get_node_names_and_namespaces()} >= set(nodes)

    end = time.monotonic() + 60
    while time.monotonic() < end and not complete():
        discover()
        ex.spin_once(timeout_sec=0.05)
    settle = time.monotonic() + 1.0       # a few more of each (and late-found topics)
    while time.monotonic() < settle:
        discover()
        ex.spin_once(timeout_sec=0.05)
    empty = sorted(t for t, v in got.items() if not v)
    ok = complete()
    ex.shutdown()
    probe.destroy_node()
    assert ok, f'missing {sorted(must - set(got))}, silent {empty}\n' + log_text()
    return got, types


def frames_and_tree(got, types):
    """(frame_id -> topics using it, the TF tree from /tf and /tf_static)."""
    tree = TfTree()
    for m in got.get('/tf_static', []):
        tree.add(transforms(m))
    for m in got.get('/tf', []):
        tree.add(transforms(m))
    frames: dict[str, set[str]] = {}
    for topic, msgs in got.items():
        for m in msgs:
            for f in headers(m):
                if f == '':
                    assert types[topic] in NON_SPATIAL, f'{topic}: empty frame_id'
                    continue
                frames.setdefault(f, set()).add(topic)
    return frames, tree


def test_every_frame_id_resolves(tmp_path, spawn, ros_context):
    link, tty = tmp_path / 'link', str(tmp_path / 'tty')
    logs = {n: open(tmp_path / f'{n}.log', 'w') for n in ('sim', *NODES)}
    spawn(['ros2', 'run', 'minirquad_sim', 'minirquad_sim', '--link-file', str(link),
           '--symlink', tty], stdout=logs['sim'], stderr=logs['sim'], cwd=REPO)
    deadline = time.monotonic() + 10
    while not link.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert link.exists(), 'simulator did not start'
    # Every node with its defaults (capacity_node: the shipped params file, as `make demo`),
    # so the frame_id defaults are what is checked.
    args = {'bridge_node': ['-p', f'port:={tty}'],
            'capacity_node': ['--params-file', 'ros2_ws/params/capacity_node.yaml'],
            'state_publisher': []}
    for n in NODES:
        pkg = 'minirquad_driver' if n == 'bridge_node' else 'rftgls_ros'
        spawn(['ros2', 'run', pkg, n, '--ros-args', *args[n]], stdout=logs[n],
              stderr=logs[n], cwd=REPO)

    for f in logs.values():
        f.flush()
    got, types = collect(ros_context, NODES, MUST,
                         lambda: (tmp_path / 'state_publisher.log').read_text())
    frames, tree = frames_and_tree(got, types)
    assert tree.unresolved(frames, root='odom') == {}, frames
    # The frames the nodes use by default are among them (so they were checked above).
    assert PARAMETERS['frame_id'].default == 'anchor'
    assert EXTRA_PARAMETERS['marker_frame_id'][0] == 'winch_link'
    assert '/capacity_node/capacity' in frames['anchor']
    assert '/capacity_node/markers' in frames['winch_link']
    assert '/imu/data' in frames['imu_link'] and '/winch/tension' in frames['winch_link']
    # Every leg link is in the tree (from the bridge's joint states through the URDF).
    for leg in ('left_proximal_leg', 'left_distal_leg', 'right_proximal_leg',
                'right_distal_leg'):
        assert tree.root(leg) == 'odom', leg
    print({f: sorted(t) for f, t in frames.items()}, sorted(got))


SAMPLE_BAG = REPO / 'src/rftgls_ros/rftgls_ros/lab/samples/forward_L1-040_L2+000'


def test_replay_frames_resolve(tmp_path, spawn, ros_context):
    """A lab bag replayed into capacity_node with state_publisher, configured as
    replay.launch.py does: every frame_id (the bag's lab_world/camera frames, capacity_node's
    anchor and winch_link) reaches the one root lab_world."""
    logs = {n: open(tmp_path / f'{n}.log', 'w') for n in ('replay', 'capacity_node',
                                                          'state_publisher')}
    spawn(['ros2', 'run', 'rftgls_ros', 'capacity_node', '--ros-args', '--params-file',
           'ros2_ws/params/capacity_node.yaml', '-p', 'robot:=prototype', '-p',
           'medium:=glass_beads', '-p', 'map_file:=maps/prototype_glass_beads.h5', '-p',
           'pull:=forward', '-p', 'pitch_topic:=/lab/theta_b', '-p', 'phi_topic:=/winch/phi',
           '-p', 'tension_component:=tether', '-p',
           'tension_frame_id:=lab_world', '-p', 'freshness_source:=receipt_time'],
          stdout=logs['capacity_node'], stderr=logs['capacity_node'], cwd=REPO)
    spawn(['ros2', 'run', 'rftgls_ros', 'state_publisher', '--ros-args', '-p',
           'robot:=prototype', '-p', 'odom_frame:=lab_world', '-p',
           'pitch_topic:=/lab/theta_b'],
          stdout=logs['state_publisher'], stderr=logs['state_publisher'], cwd=REPO)
    spawn(['ros2', 'run', 'rftgls_ros', 'rftgls_lab_replay', str(SAMPLE_BAG), '--rate', '1.0',
           '--wait-subscribers', '5'],
          stdout=logs['replay'], stderr=logs['replay'], cwd=REPO)
    for f in logs.values():
        f.flush()
    got, types = collect(ros_context, ('rftgls_lab_replay', 'capacity_node', 'state_publisher'),
                         {'/tf_static', '/tf', '/winch/tension', '/capacity_node/capacity',
                          '/capacity_node/markers'},
                         lambda: '\n'.join((tmp_path / f'{n}.log').read_text() for n in logs))
    frames, tree = frames_and_tree(got, types)
    assert tree.unresolved(frames, root='lab_world') == {}, frames
    assert '/capacity_node/capacity' in frames['anchor']
    assert '/capacity_node/markers' in frames['winch_link']
