"""Replay a pull-test bag into a running ROS 2 graph: the recorded bytes, published with rclpy.

Like `ros2 bag play` (not available from pip): every connection gets a publisher of its type,
and each message's recorded CDR bytes go out unchanged (Publisher.publish accepts bytes,
docs/design/ros2-from-pip.md). Timing: the original rate (rate=1), faster (rate=k), as fast as
possible (rate=0), or lock-step (step() one message at a time, for tests). A topic whose
recorded offered QoS is transient-local (/lab/metadata, /tf_static) is published reliable +
transient-local so a late joiner still gets it; everything else reliable with a deep queue, so
a fast replay does not drop (a best-effort subscriber still may).

Feed capacity_node (its own defaults read /joint_states, /winch/tension, /winch/height):

    python -m rftgls_ros.capacity_node --ros-args -p robot:=prototype -p medium:=glass_beads \
        -p map_file:=maps/prototype_glass_beads.h5 -p pull:=forward \
        -p pitch_topic:=/lab/theta_b -p phi_topic:=/winch/phi \
        -p tension_component:=tether -p tension_frame_id:=lab_world &
    python -m rftgls_ros.lab.replay BAG [--rate 1 | --rate 4 | --rate 0] [--anchor FILE.yaml]

The robot: the replay also publishes the URDF of the anchor description on /robot_description
(std_msgs/String, transient-local, as ROS's robot_state_publisher offers it): by default the
shipped description of the bag's robot (metadata `robot`), with `--anchor FILE.yaml` that
description (it must declare the four state variables a bag measures: h, theta_b, theta_l1,
theta_l2; a bad file is one line, exit 2). Give capacity_node the same file
(`-p anchor_description_file:=FILE.yaml`); the replay prints the parameter.
"""
from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.quantities import REPLAY_RATE, WAIT_S
from rftgls_node_base.dds_loopback import during_init
from rftgls_node_base.node_main import finish, program_args, release_ros, stop_on_signals

from .bag_layout import KNOWN_TYPES, TOPICS, BagError, guard_bag_read, read_metadata
from .predict import add_anchor_arguments

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
LATCHED_TOPICS = ('/lab/metadata',)   # bags recorded without offered QoS profiles
DESCRIPTION_TOPIC = '/robot_description'


def bag_description(bag: str | Path, anchor: str | Path | None = None, state: str = ''):
    """The AnchorDescription a replay of `bag` stands for: `anchor` (lab.predict.load_anchor:
    ValueError, one line) or else the shipped description of the bag's robot; None when the
    bag's robot has no shipped description or the bag no readable metadata (nothing is
    published then; the replay itself reports a bag it cannot read)."""
    from rftgls_core.description import load_description, shipped_description

    from .bag_layout import BagError, read_metadata
    from .predict import load_anchor
    if anchor is not None:
        lab = load_anchor(anchor, state)
        return None if lab is None else lab.description
    try:
        robot = read_metadata(bag).robot
    except BagError:
        return None
    from rftgls_core.robots.presets import ROBOTS
    if robot not in ROBOTS:   # the name is text from the bag: never a path
        return None
    return load_description(shipped_description(robot))


def publish_description(node: Node, desc) -> object:
    """A transient-local /robot_description publisher carrying desc's URDF (kept alive by the
    caller for late joiners); returns the publisher."""
    from std_msgs.msg import String
    pub = node.create_publisher(String, DESCRIPTION_TOPIC, LATCHED)
    pub.publish(String(data=desc.urdf_text()))
    return pub


def message_class(msgtype: str):
    """'pkg/msg/Name' -> the rclpy message class (rosidl_runtime_py is not in the wheels).

    Only the lab layout's types (bag_layout.KNOWN_TYPES) are resolved: the type text comes
    from the bag, and importing whatever module a file names would let a bag run code.
    BagError for anything else.
    """
    if msgtype not in KNOWN_TYPES:
        raise BagError(f'message type {msgtype!r} is not one of the lab layout\'s types')
    pkg, _, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


def latched(conn) -> bool:
    """Replay a topic transient-local when its recorder offered it so (the offered QoS
    profiles in the bag's metadata), or, for a bag without profiles, when it is a known
    latched topic of the lab layout."""
    from rosbags.interfaces import QosDurability
    profiles = getattr(conn.ext, 'offered_qos_profiles', None) or []
    if profiles:
        return any(q.durability == QosDurability.TRANSIENT_LOCAL for q in profiles)
    return conn.topic in LATCHED_TOPICS


class BagReplayer:
    """Publishes a bag's messages from `node`. Use step() for lock-step or run() for timing."""

    def __init__(self, node: Node, bag: str | Path, topics: list[str] | None = None,
                 skip_images: bool = False):
        from rosbags.rosbag2 import Reader
        self.node = node
        read_metadata(bag)     # a bag that is not a lab pull test: BagError, nothing published
        self.reader = Reader(bag)
        guard_bag_read(bag, self.reader.open)
        conns = [c for c in self.reader.connections
                 if (topics is None or c.topic in topics)
                 and not (skip_images and 'image' in c.topic)]
        # Only the lab layout's topics with their own types are replayed (see message_class);
        # anything else a recorder added is skipped, and said.
        self.skipped = sorted({f'{c.topic} ({c.msgtype})' for c in conns
                               if TOPICS.get(c.topic, ('',))[0] != c.msgtype})
        if self.skipped:
            node.get_logger().warning('not replaying topics outside the lab layout: '
                                      + ', '.join(self.skipped))
        conns = [c for c in conns if TOPICS.get(c.topic, ('',))[0] == c.msgtype]
        self.publishers = {}
        for c in conns:
            if c.topic not in self.publishers:
                qos = LATCHED if latched(c) else 100
                self.publishers[c.topic] = node.create_publisher(message_class(c.msgtype),
                                                                 c.topic, qos)
        # rosbags reads EVERY connection when given none: an empty selection is no messages.
        self._it = self.reader.messages(connections=conns) if conns else iter(())
        self.count = 0

    def step(self) -> tuple[str, int] | None:
        """Publish the next message; (topic, log time ns), or None at the end."""
        try:
            conn, t_ns, raw = next(self._it)
        except StopIteration:
            return None
        # bytes(): rclpy wants bytes, not the memoryview rosbags may hand out.
        self.publishers[conn.topic].publish(bytes(raw))
        self.count += 1
        return conn.topic, t_ns

    def run(self, rate: float = 1.0, spin=None, stopped=lambda: False) -> int:
        """Publish everything with the recorded spacing divided by `rate` (0: no waiting).
        spin(timeout_s) is called while waiting (e.g. an executor's spin_once); the replay
        ends early when stopped() is true."""
        t_first = None
        wall0 = time.monotonic()
        while not stopped():
            item = self.step()
            if item is None:
                break
            _, t_ns = item
            if t_first is None:
                t_first = t_ns
            if rate > 0:
                due = wall0 + (t_ns - t_first) * 1e-9 / rate
                while (left := due - time.monotonic()) > 0 and not stopped():
                    if spin:
                        spin(min(left, 0.05))
                    else:
                        time.sleep(min(left, 0.05))
            elif spin:
                spin(0.0)
        return self.count

    def close(self) -> None:
        self.reader.close()
        for p in self.publishers.values():
            self.node.destroy_publisher(p)


def build_parser() -> argparse.ArgumentParser:
    ap = RftglsParser(prog='rftgls_lab_replay',
                      description='publish a pull-test bag (recorded bytes)')
    ap.add_argument('bag')
    ap.add_argument('--rate', type=REPLAY_RATE.arg, default=1.0,
                    help='speed factor (1 = original timing, 0 = as fast as possible)')
    ap.add_argument('--topics', nargs='*', help='only these topics')
    ap.add_argument('--skip-images', action='store_true')
    ap.add_argument('--wait-subscribers', type=WAIT_S.arg, default=1.0,
                    help='s to wait for discovery before the first message')
    ap.add_argument('--no-description', action='store_true',
                    help='publish no /robot_description (another node does, e.g. '
                         'state_publisher in replay.launch.py)')
    add_anchor_arguments(ap)
    return ap


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The replay's options from argv (default sys.argv[1:]), ROS arguments stripped (they go
    to rclpy: a launch file's node name, remappings)."""
    return build_parser().parse_args(program_args(argv, 'rftgls_lab_replay'))


def main(argv: list[str] | None = None) -> int:
    code = _main(argv)
    if argv is None:       # as the program: end now (node_main.finish)
        release_ros()
        finish(code)
    return code


@cli_contract('replay')
def _main(argv: list[str] | None) -> int:
    args = parse_args(argv)
    try:   # before ROS starts: a bad description or bag is one line, exit 2
        desc = None if args.no_description else bag_description(args.bag, args.anchor,
                                                                args.anchor_state)
        read_metadata(args.bag)   # only a lab pull test is replayed into the live graph
    except ValueError as exc:   # BagError is one
        print(f'replay: error: {" ".join(str(exc).split())}', file=sys.stderr)
        return 2
    if desc is not None:
        print(f'robot_description: {desc.name} from {desc.source}; capacity_node: '
              f'-p anchor_description_file:={desc.source}')
    stop = stop_on_signals()
    with during_init():
        rclpy.init(args=['rftgls_lab_replay', *(sys.argv[1:] if argv is None else argv)],
                   signal_handler_options=SignalHandlerOptions.NO)
    node = Node('rftgls_lab_replay')   # the node is named as its executable
    try:
        rep = BagReplayer(node, args.bag, args.topics, args.skip_images)
        if desc is not None:
            publish_description(node, desc)
        # Give DDS discovery a moment, or the first messages go to nobody.
        end = time.monotonic() + args.wait_subscribers
        while time.monotonic() < end and not stop.is_set():
            rclpy.spin_once(node, timeout_sec=0.05)
        n = rep.run(args.rate, spin=lambda t: rclpy.spin_once(node, timeout_sec=t),
                    stopped=stop.is_set)
        print(f'replayed {n} messages from {args.bag}')
        # keep the latched metadata alive a little for late joiners
        rclpy.spin_once(node, timeout_sec=0.2)
        rep.close()
    except BagError as exc:
        print(f'replay: error: {exc}', file=sys.stderr)
        return 2
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
