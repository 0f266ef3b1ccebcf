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
package.xml declares what the installed code imports and starts, and nothing else, as exec_depend.

rosdep installs a package's exec_depends on a user's machine: a module imported but not
declared breaks there (matplotlib for plot_file), one declared but not imported is installed
for nothing.  The list is derived from the imports of the installed Python packages and of the
installed launch file, and from the packages whose nodes the launch file starts (RViz), read
with ast, so a new import (numpy in the simulator, say) shows up here until it is declared.
Optional packages (pip only) are named in package.xml with the line that installs them.
"""

import ast
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ElementTree

import pytest

ROOT = Path(__file__).resolve().parents[1]
# The Python packages setup.py installs.
INSTALLED = ('motion_challenges', 'sim_diffdrive')
# rosdep keys of the modules that are not ROS packages of their own name.
ROSDEP_KEYS = {
    'matplotlib': 'python3-matplotlib',
    'numpy': 'python3-numpy',
    'PIL': 'python3-pil',
    'pytest': 'python3-pytest',
    'yaml': 'python3-yaml',
}
# ROS packages a Python module of the same name comes from.
ROS_PACKAGES = {'ament_index_python', 'builtin_interfaces', 'geometry_msgs', 'nav_msgs',
                'rcl_interfaces', 'rclpy', 'rosgraph_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs',
                'tf2_msgs'}
# ROS packages the launch file imports or starts nodes of.
LAUNCH_PACKAGES = {'launch', 'launch_ros', 'rviz2', 'tf2_ros'}
# Optional dependencies (pip packages without a rosdep key): each imported only by the module of
# the feature that needs it, which the simulator imports only when that feature is asked for and
# runs without when it is missing (sim_diffdrive/taps/__init__.py).  Not exec_depends.
OPTIONAL = {
    'mcap': ['sim_diffdrive/taps/recorder.py'],  # record_file
    'foxglove': ['sim_diffdrive/taps/foxglove_live.py'],  # foxglove_port
    'rerun': ['sim_diffdrive/taps/view.py'],  # view_port (the module of rerun-sdk)
    'rerun_cli': ['sim_diffdrive/taps/view.py'],  # view_port (its rerun program)
}
# The pip package of each optional module, as package.xml names it.
PIP_PACKAGES = {'mcap': 'mcap', 'foxglove': 'foxglove-sdk', 'rerun': 'rerun-sdk',
                'rerun_cli': 'rerun-sdk'}
LAUNCH_FILES = sorted((ROOT / 'launch').glob('*.launch.py'))


def third_party_imports():
    """Return {top-level module: [files importing it]} for the installed packages."""
    found = {}
    for package in INSTALLED:
        for path in sorted((ROOT / package).rglob('*.py')):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0:
                    names = [node.module]
                else:
                    continue
                for name in names:
                    top = name.partition('.')[0]
                    if top not in sys.stdlib_module_names and top not in INSTALLED:
                        found.setdefault(top, set()).add(str(path.relative_to(ROOT)))
    return {module: sorted(files) for module, files in found.items()}


def launch_needs():
    """Return {ROS package or module: [launch files]}: their imports and the nodes they run."""
    found = {}
    for path in LAUNCH_FILES:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module.partition('.')[0]]
            elif isinstance(node, ast.Import):
                names = [alias.name.partition('.')[0] for alias in node.names]
            elif isinstance(node, ast.Call) and getattr(node.func, 'id', None) == 'Node':
                package = next(k.value for k in node.keywords if k.arg == 'package')
                names = [package.value] if isinstance(package, ast.Constant) else []
            else:
                continue
            for name in names:
                if name not in sys.stdlib_module_names and name not in INSTALLED:
                    found.setdefault(name, set()).add(str(path.relative_to(ROOT)))
    return {name: sorted(files) for name, files in found.items()}


def needed():
    """Return {module or ROS package: [files]}: the installed code's imports and the launch's."""
    found = third_party_imports()
    for name, files in launch_needs().items():
        found[name] = sorted(set(found.get(name, [])) | set(files))
    return found


def declared(tag):
    root = ElementTree.parse(ROOT / 'package.xml').getroot()
    return {element.text.strip() for element in root.iter(tag)}


def test_the_scan_sees_the_imports_it_is_meant_to():
    imports = third_party_imports()
    # rclpy everywhere; matplotlib only inside plot_run(), imported when a plot is asked for.
    assert 'rclpy' in imports
    assert imports['matplotlib'] == ['motion_challenges/plotting.py']


def test_the_launch_scan_sees_what_the_launch_file_runs():
    needs = launch_needs()
    assert {'launch', 'launch_ros', 'rviz2', 'tf2_ros', 'yaml'} <= set(needs)
    assert 'motion_challenges' not in needs  # its own nodes are this package


def test_every_imported_module_is_an_exec_depend():
    exec_depends = declared('exec_depend')
    missing = {}
    for module, files in sorted(needed().items()):
        if module in OPTIONAL:
            continue
        assert module in ROSDEP_KEYS or module in ROS_PACKAGES | LAUNCH_PACKAGES, (
            f'{module} (needed by {files}): add its rosdep key to ROSDEP_KEYS')
        key = ROSDEP_KEYS.get(module, module)
        if key not in exec_depends:
            missing[key] = files
    assert not missing, f'imported but not declared as <exec_depend>: {missing}'


def test_optional_dependencies_stay_in_their_modules():
    imports = third_party_imports()
    for module, files in OPTIONAL.items():
        assert imports.get(module) == files, f'{module}: imported by {imports.get(module)}'
        assert module not in declared('exec_depend')


def test_package_xml_says_how_to_install_each_optional_package():
    text = (ROOT / 'package.xml').read_text()
    for module, pip_package in PIP_PACKAGES.items():
        assert re.search(rf'pip install [^\n]*\b{re.escape(pip_package)}\b', text), module


def test_no_exec_depend_goes_unused():
    keys = {ROSDEP_KEYS.get(module, module) for module in needed()}
    unused = declared('exec_depend') - keys
    assert not unused, f'declared as <exec_depend> but imported by no installed module: {unused}'


def test_package_xml_is_valid_format_3():
    package = pytest.importorskip('catkin_pkg.package')
    manifest = package.parse_package(str(ROOT / 'package.xml'))
    assert manifest.package_format == 3
    manifest.validate()
