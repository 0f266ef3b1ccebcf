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
Let a context's DDS participant go without hanging the thread that destroys its last node.

rmw_fastrtps deletes a context's participant with the context's last node, and first detaches
the participant's discovery listener: ``DomainParticipant::set_listener(nullptr)`` in
``destroy_participant``, which waits for the listener's callbacks in flight.  With the Fast DDS
2.14 of the Jazzy wheels that wait, once it has to wait at all, never ends: its deadline,
"forever" (steady_clock's max), is moved by libstdc++ to the system clock, overflows, and comes
out as a timespec with a negative tv_nsec; ``pthread_cond_timedwait`` returns EINVAL without
releasing the mutex, and the loop calls it again, holding the mutex all along.  The callback
it waits for can never finish (its guard takes that mutex to count itself out), the discovery
threads queue up behind it, and ``destroy_node()`` spins at 100 % of a core, holding the GIL
(eProsima/Fast-DDS#6513 is the same loop where the mutex is released, a spin but no hang).

``release_participant(handle)`` makes that call first, with a deadline that does not overflow:
it waits for the callbacks in flight the ordinary way (they take microseconds), and rmw's own
call then finds nothing to wait for.  It is for a context about to go: without its listener,
a context's graph (node names, publisher counts) no longer follows discovery.

Where a context's last node goes is often not where the context ends (a test destroys its
nodes, then the fixture shuts the context down).  ``ParticipantHold(context)`` holds the
participant from the start with a node of no entities and, on release(), releases the
participant and destroys that node last.
"""

from contextlib import contextmanager
import ctypes
import functools
import os
import secrets

import rclpy
from rclpy.context import Context
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.utilities import get_rmw_implementation_identifier
from sim_diffdrive.dds_profile import use_package_profile

# The holding nodes' names: hidden (a leading underscore) from `ros2 node list`; the process
# id, then random hex, so that `ros2 node list -a` finds no two nodes of one name (containers
# on one network can all be process 1).
HOLDER_NAME = '_participant_holder_{pid}_{suffix}'

# Fast DDS's ReturnCode_t::RETCODE_OK.
_RETCODE_OK = 0
# What set_listener waits at most for the callbacks in flight: long enough to stand for
# "until they end" (each takes microseconds), short enough that steady_clock::now() plus it,
# moved to the system clock, stays far from overflowing.
_WAIT_S = 24 * 3600
# DomainParticipant::set_listener(DomainParticipantListener*, std::chrono::seconds)
_SET_LISTENER = ('_ZN8eprosima7fastdds3dds17DomainParticipant12set_listenerEPNS1_'
                 '25DomainParticipantListenerENSt6chrono8durationIlSt5ratioILl1ELl1EEEE')
# rmw_fastrtps_cpp::get_domain_participant(rmw_node_t*) (rmw_fastrtps_cpp/get_participant.hpp)
_GET_PARTICIPANT = '_ZN16rmw_fastrtps_cpp22get_domain_participantEP10rmw_node_s'


def _loaded(soname):
    """Return the library already in this process (rmw loads it with the first node)."""
    return ctypes.CDLL(soname, mode=os.RTLD_NOLOAD | os.RTLD_LAZY)


@functools.cache
def _functions():
    """Return the three functions, or () where a library or symbol is not what it expects."""
    try:
        rmw_handle = _loaded('librcl.so').rcl_node_get_rmw_handle
        rmw_handle.restype, rmw_handle.argtypes = ctypes.c_void_p, [ctypes.c_void_p]
        participant = getattr(_loaded('librmw_fastrtps_cpp.so'), _GET_PARTICIPANT)
        participant.restype, participant.argtypes = ctypes.c_void_p, [ctypes.c_void_p]
        # The seconds, a trivially copyable one-integer class, travel by value in a register,
        # and the ReturnCode_t, one 32-bit integer, comes back in one (x86-64 System V, AAPCS64).
        set_listener = getattr(_loaded('libfastrtps.so.2.14'), _SET_LISTENER)
        set_listener.restype = ctypes.c_uint32
        set_listener.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int64]
    except (OSError, AttributeError):  # another Fast DDS build: rmw's own wait it is
        return ()
    return rmw_handle, participant, set_listener


def release_participant(handle):
    """
    Detach the discovery listener of a node's DDS participant, after its callbacks in flight.

    handle is the rclpy implementation's node (an rclpy Node's ``handle``); its context's nodes
    are about to be destroyed.  Return whether there was a listener to detach: False under
    another RMW than rmw_fastrtps_cpp, or with a Fast DDS whose library does not have the call
    (rmw then detaches it as it always does).  ctypes lets the GIL go while it waits.
    """
    functions = _functions() if get_rmw_implementation_identifier() == 'rmw_fastrtps_cpp' else ()
    if not functions:
        return False
    rmw_handle, participant, set_listener = functions
    with handle:  # the node, and so its participant, cannot go meanwhile
        rmw_node = rmw_handle(handle.pointer)
        dds_participant = participant(rmw_node) if rmw_node else None
        if not dds_participant:
            return False
        code = set_listener(dds_participant, None, _WAIT_S)
    if code != _RETCODE_OK:
        raise RuntimeError(f'DomainParticipant::set_listener(nullptr) returned {code}')
    return True


class ParticipantHold:
    """
    Hold context's DDS participant until release(), then let it go the safe way.

    The holder, an rcl node of no publisher, subscription or service (no rosout, no
    parameters), is the context's first node and, released, its last: whichever other node
    goes last, the participant stays until release(), which detaches its listener
    (release_participant) before destroying the holder.  Also a context manager.
    """

    def __init__(self, context):
        use_package_profile()  # the holder is often the process's first participant
        self.name = HOLDER_NAME.format(pid=os.getpid(), suffix=secrets.token_hex(4))
        self._holder = rclpy_implementation.Node(self.name, '', context.handle, None, False, False)

    def release(self):
        """Detach the participant's listener, then destroy the holder (once; then a no-op)."""
        holder, self._holder = self._holder, None
        if holder is not None:
            try:
                release_participant(holder)
            finally:
                holder.destroy_when_not_in_use()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


@contextmanager
def held_context(args=None, domain_id=None):
    """Yield a new rclpy Context, its participant held and let go the safe way, then shut down."""
    context = Context()
    rclpy.init(args=args, context=context, domain_id=domain_id)
    try:
        with ParticipantHold(context):
            yield context
    finally:
        rclpy.try_shutdown(context=context)
