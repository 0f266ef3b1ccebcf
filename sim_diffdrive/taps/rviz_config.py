# Copyright 2026 motion_challenges contributors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
RViz for a namespaced robot or a fleet: rviz/unicycle.rviz, rewritten for its frames and topics.

A fleet's displays go on a fixed frame ``world`` the launch file ties to every odometry frame
(or on the map's).  No ROS imports: launch/unicycle.launch.py uses it.
"""

import collections
import copy

import yaml

FLEET_FRAME = 'world'
ODOM_FRAME = 'odom'
BASE_FRAME = 'base_footprint'
_PER_ROBOT = ('rviz_default_plugins/Odometry', 'rviz_default_plugins/Path',
              'rviz_default_plugins/Axes', 'rviz_default_plugins/LaserScan')
# Displays of the simulator's own topics (the map), in its namespace rather than per robot.
_PER_SIMULATOR = ('rviz_default_plugins/Map',)
_TOPIC_KEYS = ('Topic', 'Update Topic')
_POSE_TOOL = 'rviz_default_plugins/SetInitialPose'

RobotView = collections.namedtuple('RobotView', 'name odom_frame base_frame topics')


def robot_views(namespace='', robots=()):
    """Return a RobotView per robot (one unnamed for none): frames as unicycle_sim names them."""
    prefix = namespace.strip('/')
    return [RobotView(name, *(_prefixed(name, _prefixed(prefix, frame))
                              for frame in (ODOM_FRAME, BASE_FRAME)),
                      ''.join(f'/{part}' for part in (prefix, name) if part))
            for name in robots or ['']]


def rviz_config(template, namespace='', robots=(), fixed_frame=None):
    """Return the RViz template (YAML text) for namespace and robots, on fixed_frame if given."""
    config = yaml.safe_load(template)
    views = robot_views(namespace, robots)
    manager = config['Visualization Manager']
    manager['Global Options']['Fixed Frame'] = fixed_frame or (
        FLEET_FRAME if robots else views[0].odom_frame)
    prefix = namespace.strip('/')
    displays = []
    for display in manager['Displays']:
        if display['Class'] in _PER_SIMULATOR:
            displays.append(_with_topics(display, f'/{prefix}' if prefix else ''))
        elif display['Class'] in _PER_ROBOT:
            displays += [_for_robot(display, view, label=bool(robots)) for view in views]
        else:
            displays.append(display)
    manager['Displays'] = displays
    # The pose tool only without robots: it gives a pose in the fixed frame, the robot's odom.
    manager['Tools'] = [
        _with_topics(tool, views[0].topics) if tool['Class'] == _POSE_TOOL else tool
        for tool in manager.get('Tools', []) if tool['Class'] != _POSE_TOOL or not robots]
    where = ', '.join(filter(None, (namespace and f"namespace /{namespace.strip('/')}",
                                    robots and f"robots {', '.join(robots)}")))
    return (f'# Written by launch/unicycle.launch.py from rviz/unicycle.rviz for {where}.\n'
            + yaml.safe_dump(config, sort_keys=False))


def _for_robot(display, view, label):
    display = _with_topics(display, view.topics)
    if label:
        display['Name'] = f"{display['Name']} {view.name}"
    if display['Class'] == 'rviz_default_plugins/Axes':
        display['Reference Frame'] = view.base_frame
    return display


def _with_topics(display, topics):
    """Return a copy of display reading its topics under topics (absolute: '/site', or '')."""
    display = copy.deepcopy(display)
    for key in _TOPIC_KEYS:
        if key in display:
            topic = display[key]['Value'].lstrip('/')
            display[key]['Value'] = f'{topics}/{topic}'
    return display


def _prefixed(prefix, frame):
    return f'{prefix}/{frame}' if prefix else frame
