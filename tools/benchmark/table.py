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
The table: a row's fields, number formats, the printed table, the machine line and the JSON.

A row is a dict with the fields the table prints (measure, this project, reference, target,
result) plus a note and the raw numbers (data) that only the JSON carries.
"""

import json
import math
import os
from pathlib import Path
import sys

import numpy as np

# Column headers and the widths a cell wraps at.
_HEADER = ('#', 'measure', 'this project', 'reference', 'target', 'result')
_WIDTHS = (2, 34, 38, 38, 12, 6)


def row(measure, project, reference, target, result, note, **data):
    return {'measure': measure, 'project': project, 'reference': reference, 'target': target,
            'result': result, 'note': note, 'data': data}


def met(ok):
    return 'met' if ok else 'missed'


def fmt_small(value, decimals=4):
    """Format with fixed decimals, or in scientific notation when that would show zeros."""
    if value != 0.0 and abs(value) < 10.0 ** -(decimals - 1):
        return f'{value:.1e}'
    return f'{value:.{decimals}f}'


def fmt_deg(values):
    return f'mean {fmt_small(float(np.mean(values)))}, max {fmt_small(float(np.max(values)))} deg'


def fmt_closure(mm, deg):
    return f'{fmt_small(mm, 3)} mm, {fmt_small(deg)} deg'


def fmt_x(factor):
    return f'{factor:.1f}x' if math.isfinite(factor) else '-'


def fmt_rtfs(rtfs):
    return ', '.join(f'{scenario} {fmt_x(value)}' for scenario, value in rtfs.items())


def machine():
    """Return the cores, CPU model, load average and Python version of this machine."""
    model = '?'
    try:
        with open('/proc/cpuinfo') as cpuinfo:
            for line in cpuinfo:
                if line.startswith('model name'):
                    model = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return {'nproc': os.cpu_count(), 'cpu': model, 'loadavg': list(os.getloadavg()),
            'python': sys.version.split()[0]}


def _wrap(text, width):
    lines, line = [], ''
    for word in text.split(' '):
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f'{line} {word}' if line else word
    return lines + [line]


def print_table(rows, out=sys.stdout):
    """Print the rows as a table with wrapped cells, then their numbered notes."""
    table = [list(_HEADER)] + [[str(i), r['measure'], r['project'], r['reference'], r['target'],
                                r['result']] for i, r in enumerate(rows.values(), 1)]
    widths = [min(max(len(cells[i]) for cells in table), limit)
              for i, limit in enumerate(_WIDTHS)]
    for cells in table:
        wrapped = [_wrap(c, w) for c, w in zip(cells, widths)]
        for i in range(max(len(w) for w in wrapped)):
            print(' | '.join((w[i] if i < len(w) else '').ljust(width)
                             for w, width in zip(wrapped, widths)).rstrip(), file=out)
        print('-+-'.join('-' * w for w in widths), file=out)
    print('\nNotes:', file=out)
    for i, r in enumerate(rows.values(), 1):
        print(f'{i}. {r["note"]}', file=out)


def write_json(path, report):
    """Write report to path (creating its folder) as JSON; NaN and infinity become null."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(jsonable(report), indent=2, allow_nan=False) + '\n')
    return path


def jsonable(value):
    """Return value with numpy numbers as Python ones and NaN or infinity as None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
