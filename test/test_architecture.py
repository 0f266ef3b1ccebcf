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
The house rules, checked: imports run one way, pure logic stays ROS-free, modules stay short.

The contracts live in setup.cfg ([importlinter]); these tests run import-linter on the project,
and on a copy with four wrong imports, to show that the contracts do catch each.
"""

from pathlib import Path
import shutil
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('motion_challenges', 'sim_diffdrive')
MAX_LINES = 500
_LINT = ('import sys; from importlinter.cli import lint_imports; '
         'sys.exit(lint_imports(config_filename="setup.cfg", no_cache=True, no_logo=True))')


def lint_imports(root):
    """Run import-linter with root's setup.cfg, importing root's packages; return the result."""
    # make test installs import-linter; a colcon test on a ROS machine may not have it.
    pytest.importorskip('importlinter')
    return subprocess.run([sys.executable, '-c', _LINT], cwd=root, capture_output=True,
                          text=True, env={'PYTHONPATH': str(root), 'PATH': '/usr/bin:/bin'},
                          timeout=60)


def test_the_project_keeps_its_import_contracts():
    result = lint_imports(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert '3 kept, 0 broken' in result.stdout


# (module, the wrong import added to it, what the report must say of it)
WRONG_IMPORTS = (
    ('sim_diffdrive/kinematics.py', 'from motion_challenges import plans',
     'sim_diffdrive is not allowed to import motion_challenges'),
    ('motion_challenges/plans.py', 'import rclpy',
     'motion_challenges.plans is not allowed to import rclpy'),
    ('sim_diffdrive/lockstep/owner.py', 'from sim_diffdrive.sim import node',
     'sim_diffdrive.lockstep.owner -> sim_diffdrive.sim.node'),
    ('sim_diffdrive/taps/recorder.py', 'from sim_diffdrive.lockstep import counter',
     'sim_diffdrive.taps.recorder -> sim_diffdrive.lockstep.counter'),
)


def test_each_import_against_the_rules_breaks_a_contract(tmp_path):
    # One copy with all four wrong imports, linted once (import-linter's start and the import
    # graph of both packages are most of a run's CPU): each contract breaks, and the report
    # names every one of the wrong imports.
    for package in PACKAGES:
        shutil.copytree(ROOT / package, tmp_path / package)
    shutil.copy(ROOT / 'setup.cfg', tmp_path)
    for module, line, _ in WRONG_IMPORTS:
        with open(tmp_path / module, 'a') as source:
            source.write(f'{line}  # noqa\n')
    result = lint_imports(tmp_path)
    assert result.returncode == 1, result.stdout + result.stderr
    assert '0 kept, 3 broken' in result.stdout, result.stdout
    missing = [broken for _, _, broken in WRONG_IMPORTS if broken not in result.stdout]
    assert not missing, result.stdout


def test_no_module_is_longer_than_500_lines():
    too_long = {}
    for folder in PACKAGES + ('tools', 'test'):
        for path in (ROOT / folder).rglob('*.py'):
            lines = len(path.read_text().splitlines())
            if lines > MAX_LINES:
                too_long[str(path.relative_to(ROOT))] = lines
    assert not too_long, f'modules over {MAX_LINES} lines: {too_long}'


def test_the_suites_scheduling_lists_name_tests_that_exist():
    # test/conftest.py places these tests and modules by name: a renamed one would drop out
    # silently.
    import conftest
    for name in conftest._LONGEST + conftest._WAITING:
        module, _, test = name.partition('::')
        source = (ROOT / 'test' / module).read_text()
        assert f'def {test}' in source, f'{name}: no such test in test/{module}'
    for module in conftest._ONE_WORKER:
        assert (ROOT / 'test' / module).is_file(), f'{module}: no such module in test/'
