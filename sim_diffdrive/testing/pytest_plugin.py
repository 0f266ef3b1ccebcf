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
The ``sim_graph`` pytest fixture: test a controller against the simulator, in lockstep.

Installing the package registers this module as a pytest plugin (entry point group
``pytest11``), so any test can take ``sim_graph``, a sim_diffdrive.harness.SimGraph on a
fresh context.  Each test process (each xdist worker) runs on a ROS domain that no other run holds
(graph.claim_domains; SIM_GRAPH_DOMAIN_ID pins one) with localhost-only discovery, exported
as ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE so that processes a test starts join it::

    def test_my_controller(sim_graph):
        sim_graph.sim()
        sim_graph.add(MyController(context=sim_graph.context,
                                   parameter_overrides=sim_graph.sim_time_params()))
        sim_graph.step_for(3.0)
        x, y, yaw = sim_graph.pose()

rclpy is imported only when a test asks for the fixture, so the plugin costs nothing to test
suites that do not use it.
"""

import pytest


@pytest.fixture
def sim_graph():
    """Yield a SimGraph (own context, isolated domain); close it and shut down afterwards."""
    from sim_diffdrive.testing.graph import SimGraph
    graph = SimGraph()
    try:
        yield graph
    finally:
        graph.close()
