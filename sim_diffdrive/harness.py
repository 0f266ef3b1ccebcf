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

"""Everything a test of robot code needs, in one import: the graph, the probe, the processes."""

from sim_diffdrive.testing.domains import DOMAIN_VARIABLE
from sim_diffdrive.testing.domains import isolated_domain_id
from sim_diffdrive.testing.graph import SimGraph
from sim_diffdrive.testing.probe import angle_error
from sim_diffdrive.testing.probe import is_moving
from sim_diffdrive.testing.probe import pose_of
from sim_diffdrive.testing.probe import Probe
from sim_diffdrive.testing.probe import stamp_s
from sim_diffdrive.testing.probe import twist
from sim_diffdrive.testing.probe import twist_of
from sim_diffdrive.testing.processes import cpu_seconds
from sim_diffdrive.testing.processes import kill_all
from sim_diffdrive.testing.processes import Process
from sim_diffdrive.testing.processes import ros_params
from sim_diffdrive.testing.processes import start
from sim_diffdrive.testing.processes import start_python
from sim_diffdrive.testing.processes import stop
from sim_diffdrive.testing.processes import stop_all

__all__ = [
    'DOMAIN_VARIABLE', 'Probe', 'Process', 'SimGraph', 'angle_error', 'cpu_seconds',
    'is_moving', 'isolated_domain_id', 'kill_all', 'pose_of', 'ros_params', 'start',
    'start_python', 'stop', 'stop_all', 'stamp_s', 'twist', 'twist_of',
]
