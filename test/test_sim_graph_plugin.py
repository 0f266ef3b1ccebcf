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
The sim_graph fixture as a user meets it: the README's example, run from a directory of its own.

The example is taken from the README as written and run by pytest in a temporary directory
outside the project (no conftest, only the installed plugin); a copy whose controller stops
too early must fail, so the example's assertions are real.
"""

from pathlib import Path
import re
import subprocess
import sys

README = Path(__file__).resolve().parents[1] / 'README.md'


def readme_example():
    text = README.read_text()
    match = re.search(r'<!-- sim_graph example -->\n```python\n(.*?)```', text, re.S)
    assert match, 'README lost its sim_graph example'
    return match.group(1)


def test_the_readme_example_passes_from_a_directory_of_its_own_and_can_fail(tmp_path):
    example = readme_example()
    (tmp_path / 'test_my_controller.py').write_text(example)
    # The same controller stopping half a second early must fail the same assertions.
    (tmp_path / 'test_stops_early.py').write_text(
        example.replace('2_000_000_000', '1_500_000_000'))
    result = subprocess.run(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-W',
         'ignore::DeprecationWarning', '-rA', 'test_my_controller.py', 'test_stops_early.py'],
        cwd=tmp_path, capture_output=True, text=True, timeout=120)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    assert '1 failed, 1 passed' in output
    assert 'PASSED test_my_controller.py::test_drives_one_metre_and_stops' in output
    assert 'FAILED test_stops_early.py::test_drives_one_metre_and_stops' in output
