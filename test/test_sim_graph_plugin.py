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
The sim_graph fixture as a user meets it: the documented examples, run from a directory.

Each example is taken from its page as written (the README's, and docs/world.md's controller
that reads the scan) and run by pytest in a temporary directory outside the project (no
conftest, only the installed plugin); a copy whose controller stops too early must fail, so
the example's assertions are real.  One pytest run takes all four files: each test is judged
by its own outcome line, and one run starts pytest, rclpy and the plugin once, not twice.
"""

from pathlib import Path
import re
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]


def page_example(page, marker):
    text = (ROOT / page).read_text()
    match = re.search(rf'<!-- {marker} -->\n```python\n(.*?)```', text, re.S)
    assert match, f'{page} lost its {marker}'
    return match.group(1)


def test_the_documented_examples_pass_from_a_directory_of_their_own_and_can_fail(tmp_path):
    readme = page_example('README.md', 'sim_graph example')
    scan = page_example('docs/world.md', 'scan example')
    # file stem -> (its text, its test, whether it must pass).  The README's controller
    # stopping half a second early must fail the same assertions; the scan's stopping a whole
    # metre before the wall must fail.
    files = {
        'test_readme_example': (readme, 'test_drives_one_metre_and_stops', True),
        'test_readme_stops_early': (readme.replace('2_000_000_000', '1_500_000_000'),
                                    'test_drives_one_metre_and_stops', False),
        'test_scan_example': (scan, 'test_stops_half_a_metre_before_the_wall', True),
        'test_scan_stops_early': (scan.replace('if ahead > 0.5:', 'if ahead > 1.0:'),
                                  'test_stops_half_a_metre_before_the_wall', False),
    }
    assert files['test_readme_stops_early'][0] != readme
    assert files['test_scan_stops_early'][0] != scan
    shutil.copytree(ROOT / 'maps', tmp_path / 'maps')  # the scan example's map
    for stem, (text, _, _) in files.items():
        (tmp_path / f'{stem}.py').write_text(text)
    result = subprocess.run(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-rA',
         *(f'{stem}.py' for stem in files)],
        cwd=tmp_path, capture_output=True, text=True, timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    assert '2 failed, 2 passed' in output, output
    assert 'warning' not in output, output  # lark's sre_parse: the plugin leaves it out
    for stem, (_, test_name, passes) in files.items():
        outcome = 'PASSED' if passes else 'FAILED'
        assert f'{outcome} {stem}.py::{test_name}' in output, output
