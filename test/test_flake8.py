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

import configparser
import os

import ament_flake8
from ament_flake8.main import main_with_errors
import pytest

PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXCLUDES = [os.path.join(PACKAGE_DIR, d) for d in ('.venv', 'build', 'install', 'log')]


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch, tmp_path):
    # ament_flake8's configuration, checked in this process: flake8's default forks a checker
    # per core, and a fork of a pytest worker that has run other tests copies its memory as
    # the children's garbage collector touches it (10 CPU s in the suite, not 7).
    config = configparser.ConfigParser()
    config.read(os.path.join(os.path.dirname(ament_flake8.__file__), 'configuration',
                             'ament_flake8.ini'))
    config['flake8']['jobs'] = '1'
    with open(tmp_path / 'flake8.ini', 'w') as ini:
        config.write(ini)
    # ament_flake8 walks the working directory for AMENT_IGNORE markers: keep that walk small.
    monkeypatch.chdir(PACKAGE_DIR)
    rc, errors = main_with_errors(argv=[PACKAGE_DIR, '--config', str(tmp_path / 'flake8.ini'),
                                        '--exclude', *EXCLUDES])
    assert rc == 0, \
        'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)
