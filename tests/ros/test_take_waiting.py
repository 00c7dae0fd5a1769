"""rftgls_node_base.take_waiting over real DDS: messages waiting in a subscription's queue are
taken in a callback, oldest first, and the executor then runs no callback for them; messages
arriving later are delivered by the executor as before."""
from __future__ import annotations

import time

import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import Int32  # noqa: E402

from rftgls_node_base.take_waiting import take_waiting  # noqa: E402


def test_waiting_messages_are_taken_oldest_first_and_not_delivered_again(ros_context):
    node = rclpy.create_node('take_waiting_test', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        delivered: list[int] = []
        sub = node.create_subscription(Int32, 'take_waiting', lambda m: delivered.append(m.data),
                                       qos)
        pub = node.create_publisher(Int32, 'take_waiting', qos)
        deadline = time.monotonic() + 10.0
        while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        for k in range(3):
            pub.publish(Int32(data=k))
        taken: list[int] = []
        while len(taken) < 3 and time.monotonic() < deadline:
            taken += [m.data for m in take_waiting(sub)]    # nothing spins meanwhile
            time.sleep(0.01)
        assert taken == [0, 1, 2]
        assert take_waiting(sub) == []
        # the executor finds nothing left of them
        executor.spin_once(timeout_sec=0.2)
        assert delivered == []
        # and still delivers what comes later
        pub.publish(Int32(data=7))
        while not delivered and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert delivered == [7]
        # at most `limit` at once, the rest left in the queue
        for k in range(4):
            pub.publish(Int32(data=10 + k))
        first: list[int] = []
        while len(first) < 2 and time.monotonic() < deadline:
            first += [m.data for m in take_waiting(sub, limit=2 - len(first))]
            time.sleep(0.01)
        assert first == [10, 11]
        time.sleep(0.1)
        assert [m.data for m in take_waiting(sub)] == [12, 13]
    finally:
        executor.shutdown()
        node.destroy_node()
