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
``motion_fleet``: one process runs one motion per robot, each in its robot's namespace.

The process's parameters reach every motion node (rclpy's global arguments): a params file can
speak to all (``/**:``) or to one (``/robot1/odom_out_and_back:``).
"""

from collections import Counter
import os
from pathlib import Path
import time

from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.motion_node import MotionNode
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.plotting import write_plot
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
from rclpy.duration import Duration
from rclpy.exceptions import InvalidNamespaceException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.validate_namespace import validate_namespace
from sim_diffdrive.parameters import declare
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.parameters import Spec
from sim_diffdrive.participant import take_part
from sim_diffdrive.runtime import destroyed_if_refused
from sim_diffdrive.runtime import run

_MOTIONS = {'rotate_robot': RotateRobot, 'circle_back_and_forth': CircleBackAndForth,
            'timed_out_and_back': TimedOutAndBack, 'odom_out_and_back': OdomOutAndBack}

PARAMETERS = (
    Spec('robots', [], 'Names of the robots, one motion each in its robot namespace (robot1: '
         '/robot1/cmd_vel and /robot1/odom), relative to the namespace of this node. Required.',
         items=str),
    Spec('motions', ['odom_out_and_back'],
         'The motion (executable name) each robot runs: one for every robot, or one per robot '
         'in the order of robots; one of ' + ', '.join(_MOTIONS) + '.', items=str),
)


def motion_classes():
    """Return {executable name: node class} of the motions a fleet can run."""
    return dict(_MOTIONS)


def fleet_plan(robots, motions, namespace='/'):
    """Return (robot, namespace, motion) for each robot, or raise ParameterError saying why not."""
    if not robots:
        raise ParameterError("parameter 'robots' must name at least one robot, e.g. "
                             '-p robots:=[robot1,robot2]; got []')
    plan = {}  # robot namespace -> robot, in the order of robots
    for robot in robots:
        robot_ns = _robot_namespace(namespace, robot)
        if robot_ns in plan:
            raise ParameterError(f"parameter 'robots' names {robot!r} twice; got {robots!r}")
        plan[robot_ns] = robot
    if len(motions) not in (1, len(robots)):
        raise ParameterError("parameter 'motions' must have one motion for all robots or one "
                             f'per robot ({len(robots)}); got {len(motions)}: {motions!r}')
    for motion in motions:
        if motion not in _MOTIONS:
            raise ParameterError(f"parameter 'motions' names {motion!r}, which is not one of "
                                 + ', '.join(_MOTIONS))
    if len(motions) == 1:
        motions = motions * len(robots)
    return [(robot, robot_ns, motion) for (robot_ns, robot), motion in zip(plan.items(), motions)]


def _robot_namespace(namespace, robot):
    if not isinstance(robot, str) or robot.startswith(('/', '~')) or not robot:
        raise ParameterError("parameter 'robots' takes names relative to the fleet's namespace "
                             f'(robot1, site_a/robot1); got {robot!r}')
    robot_ns = namespace.rstrip('/') + '/' + robot
    try:
        validate_namespace(robot_ns)
    except InvalidNamespaceException:
        raise ParameterError(
            f"parameter 'robots' has {robot!r}, which is not a valid ROS name (letters, digits "
            "and '_', not starting with a digit, parts separated by single '/')") from None
    return robot_ns


def build_fleet(context, robots, motions, namespace='/', participant=None, **overrides):
    """
    Build one motion node per robot in context, each in its robot's namespace; return them.

    ``participant``: a lockstep Participant that answers for them all; ``overrides``:
    parameters every motion gets.  Raises ParameterError naming the robot when a motion cannot
    start, after destroying the nodes built until then.
    """
    parameter_overrides = [Parameter(name, value=value) for name, value in overrides.items()]
    nodes = []
    try:
        for robot, robot_ns, motion in fleet_plan(robots, motions, namespace):
            try:
                nodes.append(_build_motion(context, robot_ns, motion, parameter_overrides,
                                           participant))
            except ParameterError as error:
                raise ParameterError(f'robot {robot!r} ({motion}): {error}') from None
    except BaseException:
        for node in nodes:
            if node.lockstep is not None:
                node.lockstep.leave(ack_timeout=0.0)  # a participant's other nodes go on
            node.destroy_node()
        raise
    return nodes


def _build_motion(context, robot_ns, motion, parameter_overrides, participant):
    # Node-local remaps win over the process's: a global -r __ns:= (or __node:=) would
    # otherwise put every motion in one namespace under one name.
    node = _MOTIONS[motion](
        namespace=robot_ns, context=context, parameter_overrides=parameter_overrides,
        participant=participant,
        cli_args=['--ros-args', '-r', f'__ns:={robot_ns}', '-r', f'__node:={motion}'])
    if isinstance(node, RotateRobot):
        p = node.params
        missing = [name for name in ('angular_speed_deg', 'angle_deg', 'clockwise')
                   if getattr(p, name) is None]
        with destroyed_if_refused(node):
            if missing:
                raise ParameterError('rotate_robot asks nothing in a fleet: give '
                                     + ', '.join(missing) + ' as parameters (-p, or a params '
                                     'file section for this robot)')
            node.start(RotationRequest(p.angular_speed_deg, p.angle_deg, p.clockwise))
    return node


class MotionFleet(Node):
    """
    The fleet: reads ``robots`` and ``motions``; ``build()`` makes the motions.

    It has no ``done``, so runtime.run waits for the motions alone; its ``shutdown_hook`` runs
    after theirs and waits once for every robot's final stop to be acknowledged.
    """

    def __init__(self, **kwargs):
        super().__init__('motion_fleet', **kwargs)
        with destroyed_if_refused(self):
            self.params = declare(self, PARAMETERS)
            self.plan = fleet_plan(self.params.robots, self.params.motions, self.get_namespace())
        self.motions = []
        # On sim time the fleet is one participant of the lockstep: one answer per step for
        # all its motions, not one each (each costs the simulator a message and a look).
        self.lockstep = take_part(self) if self.get_parameter('use_sim_time').value else None

    def build(self):
        """Build every robot's motion in this node's context; return them."""
        self.motions = build_fleet(self.context, self.params.robots, self.params.motions,
                                   self.get_namespace(), participant=self.lockstep)
        if self.lockstep is not None and not any(map(self._answered_for, self.motions)):
            # No motion on the fleet's clock (a params file put them on wall time, say): the
            # simulator need not wait for this node.
            self.lockstep.leave(ack_timeout=0.0)
            self.lockstep = None
        for (robot, _, motion), node in zip(self.plan, self.motions):
            node.stop_ack_timeout, node.plots_itself = 0.0, False
            self.get_logger().info(
                f'{robot}: {motion} as {node.get_fully_qualified_name()} (publishes '
                f'{node.cmd_pub.topic_name}, reads {node.resolve_topic_name("odom")})')
        return self.motions

    def shutdown_hook(self):
        """Wait for the motions' final stops to be acknowledged; say how each motion ended."""
        deadline = time.monotonic() + MotionNode.stop_ack_timeout
        stops, goodbyes, unheard = [], [], []
        if self.context.ok():
            if self.lockstep is not None:
                self.lockstep.leave(ack_timeout=0.0)  # the goodbye, after every final stop
            for (robot, _, _), node in zip(self.plan, self.motions):
                # Once the time is up, each still gets a look: what was acknowledged meanwhile.
                if not node.cmd_pub.wait_for_all_acked(Duration(seconds=self._left(deadline))):
                    stops.append(robot)
                if node.lockstep is not None and not self._answered_for(node) and not (
                        node.lockstep.wait_acknowledged(self._left(deadline))):
                    goodbyes.append(robot)  # a motion that took part on its own
            if self.lockstep is not None and not self.lockstep.wait_acknowledged(
                    self._left(deadline)):
                unheard.append('the lockstep goodbye')
        unheard[:0] = [f'the {what} of {", ".join(robots)}' for what, robots in (
            ('final stop', stops), ('lockstep goodbye', goodbyes)) if robots]
        if unheard:
            self.get_logger().warning(f'Not acknowledged within {MotionNode.stop_ack_timeout:g} '
                                      f's: {" and ".join(unheard)} (a subscriber is gone or '
                                      'stalled, or the link is lossy)')
        ended = [f'{robot} {motion}: '
                 + (f'exit code {node.exit_code}' if node.done else 'stopped before the end')
                 for (robot, _, motion), node in zip(self.plan, self.motions)]
        if ended:
            self.get_logger().info('Motions: ' + '; '.join(ended))
        # The simulator no longer waits for this process.  A file that several robots were
        # given (-p for them all) gets each robot's name: fleet.png -> fleet_site_a_robot1.png.
        files = [node.get_parameter('plot_file').value for node in self.motions]
        shared = Counter(os.path.abspath(f) for f in files if f)
        for (robot, _, _), node, plot_file in zip(self.plan, self.motions, files):
            if plot_file and shared[os.path.abspath(plot_file)] > 1:
                path = Path(plot_file)
                plot_file = str(path.with_name(f"{path.stem}_{robot.replace('/', '_')}"
                                               f'{path.suffix}'))
            write_plot(node, plot_file)

    def _answered_for(self, node):
        """Return whether node takes part in lockstep through the fleet's own participant."""
        return self.lockstep is not None and getattr(node.lockstep, 'participant', None) \
            is self.lockstep

    @staticmethod
    def _left(deadline):
        return max(deadline - time.monotonic(), 0.001)


def make_fleet():
    """Build the fleet node and its motions; return them all, the fleet node last."""
    fleet = MotionFleet()
    with destroyed_if_refused(fleet):
        motions = fleet.build()
    # Last, so that its shutdown_hook runs after every motion has published its final stop.
    return [*motions, fleet]


def main(args=None):
    """Run one motion per robot until all have finished; returns the worst exit code."""
    return run(make_fleet, args, 'motion_fleet')
