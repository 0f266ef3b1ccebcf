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
The benchmark's rows (``python tools/bench.py``), from the bottom up.

``originals``: the ROS 1 programs as pure scripts, and the pure maths; ``core``: Row, the
registry, Run; ``one_process``: rows 1-6, in one process, in lockstep; ``processes``: rows 7-12,
the executables over DDS; ``fleet``: rows 13-17, many robots in one simulator.  A row is a
function ``@row('group') def key(run): return Row(measure, project, reference, note, target,
met, data)``, using ``run.once(measure, *args)`` for what rows share.
"""
