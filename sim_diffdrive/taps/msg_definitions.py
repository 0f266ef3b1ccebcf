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
The full ``ros2msg`` definition of a message type, as rosbag2 writes it into MCAP schemas.

The type's .msg text, then for each type it uses (depth first, sorted, once each) a line of 80
'=', ``MSG: pkg/Type`` and that type's .msg text, read from the ament index.
"""

import itertools
import os
import re

from ament_index_python.packages import get_package_share_directory
from ament_index_python.packages import PackageNotFoundError

SEPARATOR = '=' * 80
# A field's type at the start of a line of a .msg ('geometry_msgs/Pose[] poses'): the pattern
# rosbag2's LocalMessageDefinitionSource uses, so the dependencies come out in the same order.
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string'))


def type_name(message_class):
    """Return a message class's ROS 2 type name, e.g. 'nav_msgs/msg/Odometry'."""
    package = message_class.__module__.partition('.')[0]
    return f'{package}/msg/{message_class.__name__}'


def message_class(node, topic, msg, types):
    """Return the class of msg (a message, or its CDR bytes: cached in types) node has on topic."""
    if not isinstance(msg, bytes):
        return type(msg)
    if topic not in types:  # the type of node's publisher or subscription on topic
        found = [entity.msg_type for entity in itertools.chain(
            node.publishers, node.subscriptions) if entity.topic_name == topic]
        if not found:
            raise LookupError(f'{node.get_fully_qualified_name()} has no publisher or '
                              f'subscription on {topic}')
        types[topic] = found[0]
    return types[topic]


def message_definition(name):
    """Return the ros2msg definition of 'pkg/msg/Type' or 'pkg/Type' (LookupError: no .msg)."""
    seen = set()

    def with_dependencies(name):
        text = _msg_text(name)
        package = name.partition('/')[0]
        field_types = {match.group(1) for match in _FIELD_TYPE.finditer(text)} - _PRIMITIVES
        for dependency in sorted({t if '/' in t else f'{package}/{t}' for t in field_types}):
            if dependency not in seen:
                seen.add(dependency)
                text += f'\n{SEPARATOR}\nMSG: {dependency}\n' + with_dependencies(dependency)
        return text

    return with_dependencies(name)


def _msg_text(name):
    parts = name.split('/')
    package, kind, type_ = (parts[0], 'msg', parts[1]) if len(parts) == 2 else parts
    try:
        path = os.path.join(get_package_share_directory(package), kind, f'{type_}.msg')
        with open(path, encoding='utf-8', newline='') as msg_file:
            return msg_file.read()
    except (PackageNotFoundError, OSError) as error:
        raise LookupError(f'no .msg definition of {name} in the ament index ({error})')
