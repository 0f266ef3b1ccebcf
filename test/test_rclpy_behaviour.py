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
The rclpy behaviours that sim_diffdrive/lockstep/counter.py relies on, pinned one by one.

(And the one that sim_diffdrive/parameters.py relies on, the last test: where a node's
overrides are.)

MessageCounter wraps an existing node's entities by rebinding their attributes, and runs the
calls of a sim-time timer that the EventsExecutor's duplicate timer events made rcl skip;
nothing in rclpy's API promises what that needs.  These tests pin it as Jazzy's rclpy 7.1
behaves (the docs name 7.1.6; checked with the venv's 7.1.5 wheels), raw rclpy only, no
counter: each is named for one behaviour, so an rclpy update that changes one fails here by
name rather than somewhere in the lockstep.
"""

import time

import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time import Time
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import String

EXECUTORS = pytest.mark.parametrize('executor_class', [SingleThreadedExecutor, EventsExecutor])
_NS = 1_000_000_000


def _spin_until(executor, done, timeout_s=3.0):
    """Spin executor one event at a time until done() or timeout_s of wall time; return done()."""
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.02)
    return done()


def _spin_for(executor, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.02)


def _sim_time_node(context, name):
    return Node(name, context=context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])


@EXECUTORS
@pytest.mark.parametrize('raw', [False, True])
def test_a_subscriptions_callback_attribute_is_read_at_dispatch(ros_context, executor_class,
                                                                raw):
    node = Node('listener', context=ros_context)
    executor = executor_class(context=ros_context)
    try:
        created, rebound = [], []
        sub = node.create_subscription(String, 'pinned', created.append, 10, raw=raw)
        sub.callback = rebound.append  # after creation, as MessageCounter.wrap_new does
        pub = node.create_publisher(String, 'pinned', 10)
        executor.add_node(node)

        def heard():
            pub.publish(String(data='x'))
            return bool(rebound)
        assert _spin_until(executor, heard), 'the rebound subscription callback never ran'
        assert created == []
        assert isinstance(rebound[0], bytes if raw else String)
    finally:
        executor.shutdown()
        node.destroy_node()


@EXECUTORS
def test_a_timers_callback_attribute_is_read_at_dispatch(ros_context, executor_class):
    node = Node('ticker', context=ros_context)
    executor = executor_class(context=ros_context)
    try:
        created, rebound = [], []
        timer = node.create_timer(0.01, lambda: created.append(1))
        timer.callback = lambda: rebound.append(1)
        executor.add_node(node)
        assert _spin_until(executor, lambda: rebound), 'the rebound timer callback never ran'
        assert created == []
    finally:
        executor.shutdown()
        node.destroy_node()


def test_an_instance_publish_shadows_the_method_and_node_publishers_are_those_created(
        ros_context):
    node = Node('talker', context=ros_context)
    try:
        pub = node.create_publisher(String, 'pinned', 10)
        same = [p for p in node.publishers if p is pub]
        assert same == [pub], 'node.publishers does not hold the object create_publisher gave'
        sent = []
        publish = pub.publish

        def counted(msg):
            sent.append(msg.data)
            publish(msg)
        pub.publish = counted
        same[0].publish(String(data='x'))  # as any code holding the publisher calls it
        assert sent == ['x']
    finally:
        node.destroy_node()


@EXECUTORS
def test_the_time_sources_clock_subscription_is_in_node_subscriptions_and_wrappable(
        ros_context, executor_class):
    node = _sim_time_node(ros_context, 'sim_timed')
    executor = executor_class(context=ros_context)
    try:
        clock_subs = [s for s in node.subscriptions if s.msg_type is ClockMsg]
        assert [s.topic_name for s in clock_subs] == ['/clock']
        heard = []
        callback = clock_subs[0].callback

        def wrapped(msg):
            callback(msg)  # the TimeSource's own: sets the node's clock
            heard.append(node.get_clock().now().nanoseconds)
        clock_subs[0].callback = wrapped
        pub = node.create_publisher(ClockMsg, '/clock', 10)
        executor.add_node(node)

        def clocked():
            pub.publish(ClockMsg(clock=Time(seconds=7).to_msg()))
            return bool(heard)
        assert _spin_until(executor, clocked), 'the wrapped /clock callback never ran'
        assert heard[0] == 7 * _NS
    finally:
        executor.shutdown()
        node.destroy_node()


@EXECUTORS
def test_rcl_has_moved_a_sim_time_timers_schedule_on_when_its_callback_runs(
        ros_context, executor_class):
    # on_schedule reads time_until_next_call() in the callback as the time to its next due.
    node = _sim_time_node(ros_context, 'moved_on')
    executor = executor_class(context=ros_context)
    try:
        clock = node.get_clock()
        runs = []
        timer = node.create_timer(
            1.0, lambda: runs.append((clock.now().nanoseconds, timer.time_until_next_call())))
        executor.add_node(node)
        clock.set_ros_time_override(Time(nanoseconds=_NS))
        assert _spin_until(executor, lambda: runs), 'the due timer never ran'
        assert runs == [(_NS, _NS)]
    finally:
        executor.shutdown()
        node.destroy_node()


def test_the_events_executor_duplicates_a_sim_time_timer_event(ros_context):
    # Its timers manager queues a timer's event for every update of its timers that finds the
    # timer due, and runs rcl's call for each event, due or not.  Two clock updates queued
    # before the executor gets to them (a loaded executor, /clock messages behind each other)
    # find the timer due twice: it runs twice for its one due time, 1 s, and each run moves
    # rcl's schedule a period on.  (The TimeSource sets the clock just so for each /clock.)
    node = _sim_time_node(ros_context, 'duplicated')
    executor = EventsExecutor(context=ros_context)
    try:
        clock = node.get_clock()
        runs = []
        timer = node.create_timer(1.0, lambda: runs.append(clock.now().nanoseconds))
        executor.add_node(node)
        _spin_for(executor, 0.1)
        assert runs == [] and timer.time_until_next_call() == _NS
        clock.set_ros_time_override(Time(nanoseconds=_NS))
        clock.set_ros_time_override(Time(nanoseconds=_NS + 1))
        _spin_for(executor, 0.3)
        assert runs, 'the due timer never ran'
        assert runs != [_NS + 1], ("rclpy no longer duplicates timer events: counter.py's "
                                   '_SimTimeCalls.catch_up can go')
        assert runs == [_NS + 1, _NS + 1]
        assert timer.time_until_next_call() == 2 * _NS - 1  # due at 3 s: two periods on
    finally:
        executor.shutdown()
        node.destroy_node()


def test_a_nodes_given_parameters_are_in_its_parameter_overrides_declared_or_not(
        ros_context, tmp_path):
    # parameters.given_parameters reads them there: rclpy 7.1 has no public accessor.
    params_file = tmp_path / 'params.yaml'
    params_file.write_text('/**:\n  ros__parameters:\n    from_file: 1\n')
    node = Node('given', context=ros_context, cli_args=[
        '--ros-args', '-p', 'from_cli:=1', '--params-file', str(params_file)],
        parameter_overrides=[Parameter('from_kwargs', value=1)])
    try:
        node.declare_parameter('from_cli', 0)
        assert {'from_cli', 'from_file', 'from_kwargs'} <= set(node._parameter_overrides), (
            "rclpy no longer keeps a node's overrides in Node._parameter_overrides: "
            'parameters.given_parameters must read them elsewhere')
    finally:
        node.destroy_node()
