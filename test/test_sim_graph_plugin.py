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


def run_pytest(directory, source):
    (directory / 'test_my_controller.py').write_text(source)
    return subprocess.run(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-W',
         'ignore::DeprecationWarning', 'test_my_controller.py'],
        cwd=directory, capture_output=True, text=True, timeout=120)


def test_the_readme_example_passes_from_a_directory_of_its_own(tmp_path):
    result = run_pytest(tmp_path, readme_example())
    assert result.returncode == 0, result.stdout + result.stderr
    assert '1 passed' in result.stdout


def test_a_controller_that_stops_early_fails_the_example(tmp_path):
    source = readme_example().replace('2_000_000_000', '1_500_000_000')
    result = run_pytest(tmp_path, source)
    assert result.returncode == 1, result.stdout + result.stderr
    assert 'assert' in result.stdout and '1 failed' in result.stdout
