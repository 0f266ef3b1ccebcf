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
``colcon build`` of a copy of this package, then the install tree as ``ros2 run`` sees it.

ros2 run looks an executable up through the ament index: the package's marker in
share/ament_index/resource_index/packages, then <prefix>/lib/<package>/<executable>.
"""

import configparser
import glob
import importlib
import os
import shutil
import subprocess
import sys

from ament_index_python.packages import get_package_prefix
from ament_index_python.packages import get_package_share_directory
from ament_index_python.resources import get_resource
import pytest

PACKAGE = 'motion_challenges'
SOURCE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NOT_SOURCE = ('.git', '.venv', 'build', 'install', 'log', '__pycache__', '*.egg-info',
              '.pytest_cache', '*.pyc')
# The interface contract (DESIGN.md): these executables must exist whatever else is added.
CONTRACT_EXECUTABLES = {'unicycle_sim', 'rotate_robot', 'circle_back_and_forth',
                        'timed_out_and_back', 'odom_out_and_back'}


def colcon():
    path = shutil.which('colcon')
    return [path] if path else [sys.executable, '-m', 'colcon']


@pytest.fixture(scope='module')
def install_prefix(tmp_path_factory):
    """Build a copy of the package with colcon; return its install prefix."""
    root = tmp_path_factory.mktemp('colcon')
    shutil.copytree(SOURCE_DIR, root / 'src' / PACKAGE,
                    ignore=shutil.ignore_patterns(*NOT_SOURCE))
    result = subprocess.run(
        [*colcon(), 'build', '--base-paths', str(root / 'src'),
         '--build-base', str(root / 'build'), '--install-base', str(root / 'install'),
         '--event-handlers', 'console_direct-'],
        cwd=root, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, (
        f'colcon build failed ({result.returncode}):\n{result.stdout}\n{result.stderr}')
    return root / 'install' / PACKAGE


@pytest.fixture
def indexed(install_prefix, monkeypatch):
    """Point the ament index at the colcon install only."""
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(install_prefix))
    return install_prefix


def installed_console_scripts(prefix):
    paths = glob.glob(str(prefix / 'lib' / 'python*' / 'site-packages' / f'{PACKAGE}-*.egg-info'
                          / 'entry_points.txt'))
    assert len(paths) == 1, f'expected one installed entry_points.txt, found {paths}'
    entry_points = configparser.ConfigParser()
    entry_points.read(paths[0])
    return dict(entry_points['console_scripts'])


def test_package_is_in_the_ament_index(indexed):
    prefix = str(indexed)
    assert get_package_prefix(PACKAGE) == prefix
    share = get_package_share_directory(PACKAGE)
    assert share == os.path.join(prefix, 'share', PACKAGE)
    content, resource_prefix = get_resource('packages', PACKAGE)
    assert resource_prefix == prefix
    assert os.path.isfile(
        os.path.join(prefix, 'share', 'ament_index', 'resource_index', 'packages', PACKAGE))
    assert os.path.isfile(os.path.join(share, 'package.xml'))
    with open(os.path.join(share, 'package.xml')) as installed, \
            open(os.path.join(SOURCE_DIR, 'package.xml')) as source:
        assert installed.read() == source.read()


# What each installed console script calls: launch() (sim_diffdrive/console.py: signals taken
# first) of the module whose main() test_faults.py, test_sim_*.py and test_motion_fleet.py call
# in the pytest process (run_main): it stands for its executable.
ENTRY_POINTS = {
    'unicycle_sim': 'sim_diffdrive.console:unicycle_sim',
    **{name: f'motion_challenges.console:{name}' for name in (
        'rotate_robot', 'circle_back_and_forth', 'timed_out_and_back', 'odom_out_and_back',
        'motion_fleet')},
}


def test_every_console_script_is_an_executable_in_lib_package(indexed):
    scripts = installed_console_scripts(indexed)
    assert CONTRACT_EXECUTABLES <= set(scripts), sorted(CONTRACT_EXECUTABLES - set(scripts))
    assert scripts == ENTRY_POINTS
    for target in scripts.values():
        module, function = target.split(':')
        assert callable(getattr(importlib.import_module(module), function)), target
    lib_dir = os.path.join(get_package_prefix(PACKAGE), 'lib', PACKAGE)
    for name in scripts:
        path = os.path.join(lib_dir, name)
        assert os.path.isfile(path), f'{name} is not installed in {lib_dir}'
        assert os.access(path, os.X_OK), f'{path} is not executable'


@pytest.mark.parametrize('folder, pattern', [
    ('config', '*.yaml'), ('launch', '*.launch.py'), ('rviz', '*.rviz')])
def test_share_files_are_installed(indexed, folder, pattern):
    share = get_package_share_directory(PACKAGE)
    sources = glob.glob(os.path.join(SOURCE_DIR, folder, pattern))
    assert sources, f'no {folder}/{pattern} in the source tree'
    for source in sources:
        assert os.path.isfile(os.path.join(share, folder, os.path.basename(source))), source


def test_installed_simulator_runs_from_the_install_tree(indexed):
    site_packages = glob.glob(str(indexed / 'lib' / 'python*' / 'site-packages'))[0]
    env = dict(os.environ, PYTHONPATH=site_packages, AMENT_PREFIX_PATH=os.pathsep.join(
        p for p in (str(indexed), os.environ.get('AMENT_PREFIX_PATH')) if p))
    where = subprocess.run(
        [sys.executable, '-c', 'import sim_diffdrive; print(sim_diffdrive.__file__)'],
        env=env, cwd=indexed, capture_output=True, text=True, timeout=30)
    assert where.stdout.strip().startswith(site_packages), where.stdout + where.stderr
    # A refused parameter makes it exit at once with the usage code, naming the parameter.
    result = subprocess.run(
        [os.path.join(indexed, 'lib', PACKAGE, 'unicycle_sim'),
         '--ros-args', '-p', 'rate_hz:=-1.0'],
        env=env, cwd=indexed, stdin=subprocess.DEVNULL, capture_output=True, text=True,
        timeout=30)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "'rate_hz'" in result.stdout + result.stderr
