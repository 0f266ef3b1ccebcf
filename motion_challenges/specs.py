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

"""The parameters the motions share: their Specs (sim_diffdrive.parameters)."""

import math

from sim_diffdrive.parameters import Spec


def rate_spec(default):
    """Return the control rate parameter, rate_hz, with the motion's default."""
    return Spec('rate_hz', default, 'Control rate [Hz] of the timer that publishes cmd_vel.',
                low=0.0, high=1000.0, low_open=True)


def out_and_back_specs(rate_hz):
    """Return the parameters of timed_out_and_back, which odom_out_and_back shares."""
    return (
        Spec('goal_distance', 1.0, 'Distance of each straight leg [m].',
             low=0.0, high=1000.0, low_open=True),
        Spec('linear_speed', 0.2, 'Forward speed [m/s].', low=0.0, high=10.0, low_open=True),
        Spec('angular_speed', 1.0, 'Turn rate [rad/s].', low=0.0, high=10.0, low_open=True),
        Spec('goal_angle', math.pi, 'Angle of each turn [rad], counter-clockwise.',
             low=0.0, high=100.0, low_open=True),
        Spec('legs', 2, 'Number of drive-and-turn legs.', low=1, high=1000),
        Spec('pause', 1.0, 'Pause after each stop [s].', low=0.0, high=3600.0),
        rate_spec(rate_hz),
    )


# Every motion declares these besides its own.
COMMON_PARAMETERS = (
    Spec('start_timeout', 10.0,
         'How long to wait for the robot (see wait_for_odom) before giving up [s, wall time], '
         'from when the goal is known (typed).',
         low=0.0, high=3600.0, low_open=True, live=True),
    Spec('wait_for_odom', True,
         'Start only once odometry has come and the node that publishes it subscribes cmd_vel '
         '(the robot). false: any cmd_vel subscriber will do (a robot without odometry); the '
         'open-loop motions then run blind and cannot confirm where the robot ended.'),
    Spec('odom_timeout', 1.0,
         'Stop and fail when no odometry came for this long mid-motion (closed loop), or, on '
         'sim time, when simulated time stood still this long with no word from the simulator '
         '[s, wall time].',
         low=0.0, high=3600.0, low_open=True, live=True),
    Spec('plot_file', '',
         'Write a PNG of the run here: the path (start, end and goal) beside the heading and '
         'the commanded and achieved speeds over time; empty = no plot. Needs matplotlib.',
         live=True),
    Spec('stamped', False,
         'Publish geometry_msgs/TwistStamped, stamped with the node clock, instead of Twist '
         "(ros2_control's diff_drive_controller takes only TwistStamped)."),
    Spec('frame_id', 'base_footprint', 'With stamped: frame_id of the commands.', live=True),
)
