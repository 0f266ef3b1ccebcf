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
docs/world.md's controller that reads the scan, run as a user runs it, with the sim_graph fixture.

The example is taken from the page as written and run by pytest in a directory of its own
that holds the example map; a copy that stops a whole metre before the wall must fail.
"""

from pathlib import Path
import re
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]


def page_example():
    text = (ROOT / 'docs' / 'world.md').read_text()
    match = re.search(r'<!-- scan example -->\n```python\n(.*?)```', text, re.S)
    assert match, 'docs/world.md lost its scan example'
    return match.group(1)


def test_the_scan_example_passes_from_a_directory_of_its_own_and_can_fail(tmp_path):
    example = page_example()
    shutil.copytree(ROOT / 'maps', tmp_path / 'maps')
    (tmp_path / 'test_stop_before_the_wall.py').write_text(example)
    early = example.replace('if ahead > 0.5:', 'if ahead > 1.0:')
    assert early != example
    (tmp_path / 'test_stops_early.py').write_text(early)
    result = subprocess.run(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-W',
         'ignore::DeprecationWarning', '-rA', 'test_stop_before_the_wall.py',
         'test_stops_early.py'],
        cwd=tmp_path, capture_output=True, text=True, timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    assert '1 failed, 1 passed' in output
    assert 'PASSED test_stop_before_the_wall.py::test_stops_half_a_metre_before_the_wall' in output
    assert 'FAILED test_stops_early.py::test_stops_half_a_metre_before_the_wall' in output
