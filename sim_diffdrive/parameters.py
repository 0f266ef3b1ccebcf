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
Declare a node's parameters from one table, refuse bad values, apply live changes.

Values are checked here, not by rclpy, so that ``-p angle_deg:=90`` (an integer) serves a float
parameter and every refusal names the parameter, its range and the value.  A parameter is live
or read-only, so no set is accepted and then ignored.
"""

from array import array
from collections.abc import Sequence
from dataclasses import dataclass
import difflib
import math
import re

from rcl_interfaces.msg import FloatingPointRange
from rcl_interfaces.msg import IntegerRange
from rcl_interfaces.msg import ParameterDescriptor
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

READ_ONLY_NOTE = ' Read-only: set at start.'
# What a bool or a str parameter refuses a value of another type with.
_MUST_BE = {bool: 'must be true or false', str: 'must be a string'}


class ParameterError(ValueError):
    """A parameter was given a value the node cannot run with."""


@dataclass(frozen=True)
class Spec:
    """
    One parameter: name, default (its type decides the parameter's type) and meaning.

    A default of None declares it without a value, ``kind`` naming its type.  ``low``/``high``
    bound numbers (and each element of a number array), ``low_open`` excludes ``low``;
    ``choices`` restricts strings, ``problem(value)`` says why one is unusable, or None (say
    frame_problem: a tf2 frame id); ``length`` fixes an array's size, ``items`` its elements'
    type (float or str); ``live`` lets it change while the node runs (else read-only).
    """

    name: str
    default: object
    description: str
    low: float = None
    high: float = None
    low_open: bool = False
    choices: tuple = ()
    problem: object = None
    length: int = None
    kind: type = None
    live: bool = False
    items: type = float

    @property
    def type_(self):
        return self.kind or (list if isinstance(self.default, list) else type(self.default))

    def descriptor(self):
        descriptor = ParameterDescriptor(
            name=self.name, description=self.description + ('' if self.live else READ_ONLY_NOTE),
            dynamic_typing=True, additional_constraints=self.constraints(),
            read_only=not self.live)
        if self.low is not None and self.high is not None:
            if self.type_ is float or (self.type_ is list and self.items is float):
                descriptor.floating_point_range = [FloatingPointRange(
                    from_value=float(self.low), to_value=float(self.high))]
            elif self.type_ is int:
                descriptor.integer_range = [IntegerRange(
                    from_value=int(self.low), to_value=int(self.high), step=1)]
        return descriptor

    def constraints(self):
        parts = []
        if self.length is not None:
            parts.append(f'{self.length} values')
        if self.high is not None:
            parts.append(self._interval())
        if self.choices:
            parts.append('one of ' + ', '.join(self.choices))
        return '; '.join(parts)

    def check(self, value):
        """Return value converted to this parameter's type, or raise ParameterError."""
        if value is None and self.default is None:
            return None
        if self.type_ in _MUST_BE:
            if not isinstance(value, self.type_):
                raise self._error(value, _MUST_BE[self.type_])
            if self.choices and value not in self.choices:
                raise self._error(value, 'must be one of ' + ', '.join(self.choices))
            if self.problem and (why := self.problem(value)):
                raise self._error(value, why)
            return value
        if self.type_ is list:
            if value is None and self.default == []:
                return []  # -p name:=[] declares the parameter without a type or value
            what = 'strings' if self.items is str else 'numbers'
            if not isinstance(value, Sequence) or isinstance(value, str):
                raise self._error(value, f'must be a list of {what}')
            if self.length is not None and len(value) != self.length:
                raise self._error(value, f'must have exactly {self.length} values')
            if self.items is str:
                if not all(isinstance(v, str) for v in value):
                    raise self._error(value, 'must be a list of strings')
                return list(value)
            return [self._number(v, float) for v in value]
        return self._number(value, self.type_)

    def _number(self, value, type_):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self._error(value, 'must be a number')
        if type_ is int and not isinstance(value, int):
            raise self._error(value, 'must be an integer')
        if type_ is float:
            value = float(value)
            if not math.isfinite(value):
                raise self._error(value, 'must be a finite number')
        too_low = self.low is not None and (
            value < self.low or (self.low_open and value == self.low))
        if too_low or (self.high is not None and value > self.high):
            raise self._error(value, 'must be in ' + self._interval())
        return value

    @property
    def unit(self):
        """Return the unit the description gives in brackets ('s' for '[s, wall time]'), or ''."""
        match = re.search(r'\[([^\],]+)[\],]', self.description)
        return match.group(1).strip() if match else ''

    def _interval(self):
        return f'{"(" if self.low_open else "["}{self.low}, {self.high}]'

    def _error(self, value, why):
        if isinstance(value, array):
            value = value.tolist()  # as rclpy hands over arrays from the command line or a set
        return ParameterError(f"parameter '{self.name}' {why}; got {value!r}")


def frame_problem(frame):
    """Return why tf2 cannot use frame as a frame id, or None."""
    if not frame.strip():
        return 'must name a frame, not be empty'
    if any(c.isspace() for c in frame):
        return 'must not hold whitespace'
    if frame.startswith('/'):
        # tf2 refuses it in a lookup, and an initialpose's frame is compared without it.
        return "must not start with '/' (tf2 frame ids have none: 'map', not '/map')"
    return None


def declare(node, specs, on_change=None):
    """
    Declare every Spec on node and return its Values: the checked values as attributes.

    Raises ParameterError naming the first unusable value.  A live parameter set at runtime is
    checked, stored converted and passed to ``on_change(name, value)``.
    """
    for spec in specs:
        # Declared without its range first, so that the check below (not rclpy's) words the
        # refusal; the full descriptor then guards later changes and shows in introspection.
        # It is also where read_only is set: the conversion below is still a set.
        descriptor = spec.descriptor()
        unbounded = ParameterDescriptor(
            name=spec.name, description=descriptor.description, dynamic_typing=True,
            additional_constraints=descriptor.additional_constraints)
        parameter = node.declare_parameter(spec.name, spec.default, unbounded)
        value = spec.check(parameter.value)
        # Compare parameter types too: [1, 0] == [1.0, 0.0], yet one is an integer array.
        if value is not None and (value != parameter.value or parameter.type_
                                  != Parameter.Type.from_parameter_value(value)):
            # Store the converted value so `ros2 param get` shows what the node runs with.
            node.set_parameters([Parameter(spec.name, value=value)])
        if descriptor.floating_point_range or descriptor.integer_range or descriptor.read_only:
            node.set_descriptor(spec.name, descriptor)
    live = {spec.name: spec for spec in specs if spec.live}
    if live:
        _LiveParameters(node, live, on_change)
    _clock_chosen_at_start(node)
    _warn_misspelt(node)
    return Values(node, specs)


def given_parameters(node):
    """
    Return the names of the parameters given to node (``-p``, a params file), declared or not.

    rclpy 7.1 has no public accessor for them: it keeps them in ``Node._parameter_overrides``
    (test_rclpy_behaviour.py pins that, so an rclpy that changes it fails there by name).
    """
    return tuple(getattr(node, '_parameter_overrides', {}))


def _warn_misspelt(node):
    """
    Warn about each parameter given to node that it has not, but has one spelt much like it.

    rclpy ignores a parameter a node never declares, without a word, so ``-p initail_x:=1``
    would start the robot at 0.  A name like none of node's is not warned about: a params file's
    ``/**`` section, or ``-p`` in a process of several nodes, gives every node the others' too.
    """
    names = list(node.get_parameters_by_prefix(''))  # use_sim_time and the specs' names
    for name in given_parameters(node):
        if node.has_parameter(name):
            continue
        # One letter off in four is 0.75 alike: a short name's typo is as close as it can be.
        cutoff = max(0.75, min(0.8, (len(name) - 1) / len(name)))  # 'z' is like nothing
        close = difflib.get_close_matches(name, names, n=1, cutoff=cutoff)
        if close:
            node.get_logger().warning(
                f"Ignoring parameter '{name}': {node.get_name()} has none by that name (did you "
                f"mean '{close[0]}'?)")


class Values:
    """A node's declared parameters as attributes (``params.rate_hz``), read from rclpy."""

    def __init__(self, node, specs):
        self._get = node.get_parameter
        self._specs = {spec.name: spec for spec in specs}

    def __getattr__(self, name):
        spec = self.__dict__['_specs'].get(name)
        if spec is None:
            raise AttributeError(f'no parameter {name!r} was declared')
        return spec.check(self._get(name).value)


def _clock_chosen_at_start(node):
    """
    Make use_sim_time read-only: these nodes choose their clock once, at start.

    Switched mid-run, the simulator's stepping and a motion's lockstep and ticks would stop
    while the set was reported successful.
    """
    node.set_descriptor('use_sim_time', ParameterDescriptor(
        name='use_sim_time', type=node.describe_parameter('use_sim_time').type,
        description='Run on simulated time from /clock (the simulator publishes it with '
                    'publish_clock).' + READ_ONLY_NOTE, read_only=True))


def live_parameters(node):
    """Return the names of node's parameters that declare() made live."""
    return frozenset(getattr(node, '_live_parameters', ()))


class _LiveParameters:
    """
    The rclpy parameter callbacks that check, store and apply a node's live parameters.

    rclpy checks a descriptor's range (in its own words, without open bounds) before any
    on-set callback, so the Spec speaks first, in the pre-set callback: a bad value is noted
    and replaced by the current one, and the on-set callback refuses the set in its words.
    """

    def __init__(self, node, specs, on_change):
        self.node = node
        self.specs = specs
        self.on_change = on_change
        self._refused = {}  # parameter name -> refusal, for the set under way
        node._live_parameters = live_parameters(node) | set(specs)
        node.add_pre_set_parameters_callback(self._convert)
        node.add_on_set_parameters_callback(self._refuse)
        node.add_post_set_parameters_callback(self._apply)

    def _convert(self, parameters):
        self._refused = {}
        converted = []
        for parameter in parameters:
            spec = self.specs.get(parameter.name)
            if spec is not None:
                try:
                    parameter = Parameter(spec.name, value=spec.check(parameter.value))
                except ParameterError as error:
                    self._refused[spec.name] = str(error)
                    current = self.node.get_parameter(spec.name)
                    parameter = Parameter(spec.name, current.type_, current.value)
            converted.append(parameter)
        return converted

    def _refuse(self, parameters):
        refused, self._refused = self._refused, {}
        reason = next((refused[p.name] for p in parameters if p.name in refused), None)
        return SetParametersResult(successful=reason is None, reason=reason or '')

    def _apply(self, parameters):
        for parameter in parameters:
            spec = self.specs.get(parameter.name)
            if spec is None:
                continue
            value = spec.check(parameter.value)
            if self.on_change is not None:
                self.on_change(spec.name, value)
            shown = repr(value) if isinstance(value, str) else value
            self.node.get_logger().info(f'{spec.name} is now {shown} {spec.unit}'.rstrip())
