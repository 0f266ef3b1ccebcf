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
The package's Fast DDS profile (fastdds_profile.xml): lost reliable samples repaired in ~10 ms.

Fast DDS reads the file named by FASTRTPS_DEFAULT_PROFILES_FILE once per process, when the
process makes its first DDS participant; ``use_package_profile()`` must therefore run before
the first node.  runtime.run() calls it for every executable, SimGraph for in-process graphs.
A file the user named already is kept: it should then set ``heartbeatPeriod`` itself.
"""

import os
from pathlib import Path

PROFILE_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'
PROFILE_FILE = Path(__file__).with_name('fastdds_profile.xml')


def use_package_profile():
    """Make Fast DDS use the package's profile unless a profile file is named already."""
    os.environ.setdefault(PROFILE_VARIABLE, str(PROFILE_FILE))
