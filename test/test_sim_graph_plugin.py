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
The sim_graph fixture as a user meets it: the documented examples, run from directories.

Each example is taken from its page as written (the README's, and docs/world.md's controller
that reads the scan) and run by pytest in a temporary directory outside the project (no
conftest, only the installed plugin); a copy whose controller stops too early must fail, so
the example's assertions are real.
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


def run_example_and_early_copy(directory, example, early, test_name):
    """Run example and its early-stopping copy with pytest in directory; check 1 of 2 fails."""
    assert early != example
    (directory / 'test_example.py').write_text(example)
    (directory / 'test_stops_early.py').write_text(early)
    result = subprocess.run(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-W',
         'ignore::DeprecationWarning', '-rA', 'test_example.py', 'test_stops_early.py'],
        cwd=directory, capture_output=True, text=True, timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    assert '1 failed, 1 passed' in output
    assert f'PASSED test_example.py::{test_name}' in output
    assert f'FAILED test_stops_early.py::{test_name}' in output


def test_the_readme_example_passes_from_a_directory_of_its_own_and_can_fail(tmp_path):
    example = page_example('README.md', 'sim_graph example')
    # The same controller stopping half a second early must fail the same assertions.
    run_example_and_early_copy(tmp_path, example,
                               example.replace('2_000_000_000', '1_500_000_000'),
                               'test_drives_one_metre_and_stops')


def test_the_scan_example_passes_from_a_directory_of_its_own_and_can_fail(tmp_path):
    example = page_example('docs/world.md', 'scan example')
    shutil.copytree(ROOT / 'maps', tmp_path / 'maps')
    # Stopping a whole metre before the wall must fail.
    run_example_and_early_copy(tmp_path, example,
                               example.replace('if ahead > 0.5:', 'if ahead > 1.0:'),
                               'test_stops_half_a_metre_before_the_wall')
