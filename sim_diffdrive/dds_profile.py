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

Fast DDS reads FASTRTPS_DEFAULT_PROFILES_FILE when the process makes its first participant, so
``use_package_profile()`` must run before the first node.  A file the user named is kept.
"""

import os
from pathlib import Path

PROFILE_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'
PROFILE_FILE = Path(__file__).with_name('fastdds_profile.xml')


def use_package_profile():
    """Make Fast DDS use the package's profile unless a profile file is named already."""
    os.environ.setdefault(PROFILE_VARIABLE, str(PROFILE_FILE))
