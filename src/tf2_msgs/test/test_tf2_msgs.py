"""The workspace's tf2_msgs is Jazzy's: the TFMessage type hash equals the one rosbags'
Jazzy type store computes from upstream's definitions (RIHS01_e369d0f0..., independent of
this build), so real RViz, Foxglove and ros2 bag read /tf and /tf_static from this stack."""
from __future__ import annotations

import json
from pathlib import Path


def test_tfmessage_type_hash_is_upstreams():
    from ament_index_python.packages import get_package_share_directory
    from rosbags.typesys import Stores, get_typestore
    desc = Path(get_package_share_directory('tf2_msgs')) / 'msg' / 'TFMessage.json'
    ours = json.loads(desc.read_text())['type_hashes'][0]['hash_string']
    ts = get_typestore(Stores.ROS2_JAZZY)
    assert ours == ts.hash_rihs01('tf2_msgs/msg/TFMessage')
    assert ours.startswith('RIHS01_e369d0f0')
