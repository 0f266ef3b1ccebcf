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
Benchmark this package against the programs it replaces and print one table (``make bench``).

Every row puts this project's figure next to a reference measured in the same run (the
original algorithm reproduced here, Euler integration, another executor, ...) and, where the
project has a target, whether it was met:

* accuracy: rotate 90 deg at 60 deg/s clockwise (timed and odom mode) against the original
  ``rotate_robot.py`` algorithm over start times spread across one second; timed out-and-back
  against rbx1's tick arithmetic; circle back-and-forth against ``move_rob.py``; the simulator's
  exact arc against forward Euler over 100 laps of a circle;
* speed: real-time factor of the three default motions on simulated time, in one process
  (lockstep, SingleThreadedExecutor and EventsExecutor) and across processes (``unicycle_sim``
  and the motion executables over DDS), with a check that two runs give identical poses;
  cmd_vel -> odom latency; simulator CPU idle and under commands; N robots in one process and
  in separate processes;
* many robots in one simulator (its ``robots`` parameter): CPU per simulated second and the
  achievable real-time factor for 1 to 256 robots, idle and commanded, the cost per robot next
  to rclpy's cost per Odometry message, and N motions against one simulator and one
  ``motion_fleet`` next to N simulator + motion pairs.

In-process rows run the real simulator node and the real motion nodes in one executor, stepped
in lockstep (sim_diffdrive.harness), so their results are exact and independent of machine
load; their context has discovery off, so nothing outside it can interfere.  Everything else
uses a ROS domain of its own (random in 1..100 unless --domain-id is given) with localhost-only
discovery, for this process and every process it starts, and all of those are stopped before
the benchmark exits.

Modules, from the bottom up:

* ``config``: row order, groups for --only, targets, and the sizes of a full or --quick run;
* ``originals``: the ROS 1 tutorial programs reproduced as pure scripts, the model robot that
  plays them without ROS, and the pure maths of the rows (yaw and closure errors, Euler);
* ``table``: a row's fields, number formats, the printed table and the JSON;
* ``graph``: the lockstep graph (the harness's SimGraph on an executor and context of its own)
  and the node that plays an original script on sim time;
* ``scenarios``: rows 1-6, in one process (accuracy against the originals, real-time factor);
* ``processes``: rows 7-10, the executables as separate processes (real-time factor, latency,
  CPU);
* ``scaling``: rows 11-12, N robots in one process and as 2N processes;
* ``fleet``: rows 13-17, many robots in one simulator process, with ``fleet_load``, the
  process that commands them (told what to do on its stdin);
* ``cli``: the command line (``python tools/bench.py [--quick] [--json PATH] [--only GROUPS]
  [--domain-id N] [--rtf X]``).
"""
