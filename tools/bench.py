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
Benchmark this package against the programs it replaces and print one table.

Usage (venv active): ``python tools/bench.py [--quick] [--json PATH] [--only GROUPS]``, or
``make bench``.  The JSON goes to out/bench.json unless --json says otherwise.  The benchmark
itself is the package tools/benchmark/ (see its __init__ for a map of its modules); Python puts
this script's folder on the path, so it imports from there.
"""

import sys

from benchmark.cli import main

if __name__ == '__main__':
    sys.exit(main())
