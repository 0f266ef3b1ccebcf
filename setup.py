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

from glob import glob

from setuptools import find_packages
from setuptools import setup

package_name = 'motion_challenges'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={'sim_diffdrive': ['fastdds_profile.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml', 'README.md']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/maps', glob('maps/*.yaml') + glob('maps/*.pgm')),
        ('share/' + package_name + '/rviz', glob('rviz/*.rviz')),
    ],
    # rclpy and the message packages come from ROS 2 (apt's /opt/ros/jazzy or the ros-* wheels
    # the Makefile installs), never from here, so colcon builds this on a ROS machine as is.
    install_requires=['setuptools'],
    extras_require={'plot': ['matplotlib'], 'test': ['pytest']},
    # Fast DDS reads fastdds_profile.xml from a path on disk.
    zip_safe=False,
    maintainer='motion_challenges maintainers',
    maintainer_email='maintainers@motion-challenges.dev',
    description='Classic ROS 1 motion tutorials on ROS 2 Jazzy with an exact unicycle simulator.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'unicycle_sim = sim_diffdrive.console:unicycle_sim',
            'rotate_robot = motion_challenges.console:rotate_robot',
            'circle_back_and_forth = motion_challenges.console:circle_back_and_forth',
            'timed_out_and_back = motion_challenges.console:timed_out_and_back',
            'odom_out_and_back = motion_challenges.console:odom_out_and_back',
            'motion_fleet = motion_challenges.console:motion_fleet',
        ],
        # The sim_graph fixture, for testing controllers against the simulator.
        'pytest11': ['sim_graph = sim_diffdrive.testing.pytest_plugin'],
    },
)
