"""The shipped RViz layout (config/capacity.rviz) uses displays that exist in Jazzy's
rviz_default_plugins (class names and message types as its plugins_description.xml lists
them) on topics the stack publishes with those types: the robot model from
/robot_description, the capacity as a Wrench, the slip as a TwistStamped, the markers."""
from __future__ import annotations

from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / 'src' / 'rftgls_ros' / 'config' / 'capacity.rviz'
# rviz_default_plugins (Jazzy) plugin class -> the message type it subscribes to
# (ros2/rviz, jazzy branch, rviz_default_plugins/plugins_description.xml).
JAZZY_DISPLAYS = {
    'rviz_default_plugins/Grid': None,
    'rviz_default_plugins/TF': None,
    'rviz_default_plugins/RobotModel': 'std_msgs/msg/String',
    'rviz_default_plugins/Wrench': 'geometry_msgs/msg/WrenchStamped',
    'rviz_default_plugins/TwistStamped': 'geometry_msgs/msg/TwistStamped',
    'rviz_default_plugins/MarkerArray': 'visualization_msgs/msg/MarkerArray',
}
# What the stack publishes there (state_publisher, capacity_node).
PUBLISHED = {
    '/robot_description': 'std_msgs/msg/String',
    '/capacity_node/capacity': 'geometry_msgs/msg/WrenchStamped',
    '/capacity_node/slip_twist': 'geometry_msgs/msg/TwistStamped',
    '/capacity_node/markers': 'visualization_msgs/msg/MarkerArray',
}


def displays():
    doc = yaml.safe_load(CONFIG.read_text())
    return doc['Visualization Manager']['Displays'], doc


def test_displays_exist_in_jazzy_and_read_published_topics():
    shown, doc = displays()
    classes = [d['Class'] for d in shown]
    assert set(classes) <= set(JAZZY_DISPLAYS), classes
    assert {'rviz_default_plugins/RobotModel', 'rviz_default_plugins/Wrench',
            'rviz_default_plugins/TwistStamped', 'rviz_default_plugins/MarkerArray'} <= \
        set(classes)
    for d in shown:
        topic = (d.get('Description Topic') or d.get('Topic') or {}).get('Value')
        if JAZZY_DISPLAYS[d['Class']] is None:
            continue
        assert PUBLISHED[topic] == JAZZY_DISPLAYS[d['Class']], (d['Class'], topic)
    robot = next(d for d in shown if d['Class'].endswith('RobotModel'))
    # /robot_description is latched: the display must ask for transient local to get it.
    assert robot['Description Source'] == 'Topic'
    assert robot['Description Topic']['Durability Policy'] == 'Transient Local'
    assert doc['Visualization Manager']['Global Options']['Fixed Frame'] == 'odom'
