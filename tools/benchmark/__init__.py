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
The rows of ``python tools/bench.py``, from the bottom up.

``originals`` (the ROS 1 programs, pure maths), ``core`` (Row, the ``@row(group)`` registry,
Run), ``one_process`` (rows 1-6), ``processes`` (7-12), ``fleet`` (13-18; ``load``, the process
that loads its simulators), ``suite`` (19, ``make test``).  A row is ``@row('group') def
key(run): return Row(measure, project, reference, note, target, met, data)``, with
``run.once(measure, *args)`` for what rows share.
"""
