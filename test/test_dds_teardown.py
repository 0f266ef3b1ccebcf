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
The DDS participant let go the safe way (sim_diffdrive/dds_teardown.py).

The hang itself needs a discovery callback in flight at the instant the participant goes, a
race these tests do not stage; they show the pieces: the participant outlives the last node
while held, its listener is detached before it goes, and the holder stays out of the way.
"""

import ctypes
import os

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.utilities import get_rmw_implementation_identifier
from sim_diffdrive import dds_teardown
from sim_diffdrive.dds_profile import PROFILE_FILE
from sim_diffdrive.dds_profile import PROFILE_VARIABLE
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.dds_teardown import ParticipantHold
from sim_diffdrive.dds_teardown import release_participant
from sim_diffdrive.harness import isolated_domain_id
from sim_diffdrive.harness import SimGraph

# DomainParticipant::get_listener() const
_GET_LISTENER = '_ZNK8eprosima7fastdds3dds17DomainParticipant12get_listenerEv'


def participant_listener(handle):
    """Return the address of the DDS listener of the participant of an rcl node handle."""
    rmw_handle, participant, _ = dds_teardown._functions()
    get_listener = getattr(dds_teardown._loaded('libfastrtps.so.2.14'), _GET_LISTENER)
    get_listener.restype, get_listener.argtypes = ctypes.c_void_p, [ctypes.c_void_p]
    with handle:
        return get_listener(participant(rmw_handle(handle.pointer)))


def test_a_held_participant_outlives_the_last_node_and_is_let_go():
    # A context of its own, held by nothing else: the user's node is its only other node.
    assert get_rmw_implementation_identifier() == 'rmw_fastrtps_cpp'
    context = Context()
    rclpy.init(context=context, domain_id=isolated_domain_id())
    try:
        with ParticipantHold(context) as hold:
            node = Node('last_of_its_context', context=context)
            node.destroy_node()
            # The participant is still there, rmw's listener on it: the holder reaches it.
            assert participant_listener(hold._holder)
            assert release_participant(hold._holder)
            assert not participant_listener(hold._holder), 'the listener is still attached'
        assert hold._holder is None
        hold.release()  # once is enough; again is a no-op
    finally:
        rclpy.try_shutdown(context=context)


def test_a_held_context_is_shut_down_with_a_node_left_in_it():
    with held_context(domain_id=isolated_domain_id()) as context:
        Node('left_to_the_context', context=context)
        assert context.ok()
    assert not context.ok()


def test_the_holder_names_the_package_profile_first(ros_context, monkeypatch):
    # Often the process's first participant: Fast DDS reads the profile file as it is made.
    monkeypatch.delenv(PROFILE_VARIABLE, raising=False)
    with ParticipantHold(ros_context):
        assert os.environ[PROFILE_VARIABLE] == str(PROFILE_FILE)


def test_the_holder_is_a_node_of_no_entities_and_a_name_of_its_own(ros_context):
    node = Node('lister', context=ros_context)
    try:
        with ParticipantHold(ros_context) as hold, ParticipantHold(ros_context) as other:
            assert hold.name != other.name and hold.name.startswith('_participant_holder_')
            names = node.get_node_names_and_namespaces()
            assert (hold.name, '/') in names and (other.name, '/') in names
            publishers = node.get_publisher_names_and_types_by_node(hold.name, '/')
            subscriptions = node.get_subscriber_names_and_types_by_node(hold.name, '/')
            assert publishers == [] and subscriptions == []
    finally:
        node.destroy_node()


def test_a_graph_of_its_own_holds_its_participant():
    with SimGraph() as graph:
        lister = graph.add(Node('lister', context=graph.context))
        assert any(name.startswith('_participant_holder_')
                   for name, _ in lister.get_node_names_and_namespaces())
