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
The ``sim_graph`` pytest fixture (entry point ``pytest11``): a SimGraph on a fresh context.

rclpy is imported only when a test asks for the fixture (README: Test your own controller).
"""

import pytest


def pytest_configure(config):
    """
    Leave out a warning users cannot act on: lark (of rosidl) imports sre_parse.

    Through the pytest11 entry point: in every pytest run where the package is installed.
    """
    config.addinivalue_line('filterwarnings', "ignore:module 'sre_:DeprecationWarning")


@pytest.fixture
def sim_graph():
    """Yield a SimGraph (own context, isolated domain); close it and shut down afterwards."""
    from sim_diffdrive.testing.graph import SimGraph
    with SimGraph() as graph:
        yield graph
