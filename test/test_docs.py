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
The documentation against the code: every example runs or is checked, every link resolves.

Fenced blocks in README.md, CONTRIBUTING.md and docs/*.md, by language:

* ``python`` runs in a fresh interpreter on this run's ROS domain and must exit 0.  After
  ``<!-- run with: COMMAND -->`` it runs while COMMAND (an executable of this package) runs;
  a ``text`` block after ``<!-- output -->`` right below it must be what it prints.  The
  README's sim_graph example is run by test_sim_graph_plugin.py.
* ``bash`` and ``console`` (there only ``$`` lines are commands): an executable of this
  package, as such or through ``ros2 run``, is built in a fresh context from the command's own
  ``--ros-args``, so a parameter it does not declare, a value it refuses or a missing params
  file fails.  ``ros2 launch`` arguments must be declared by the launch file, ``ros2 param``
  must name a parameter (live when shown succeeding), ``make`` targets must exist, and so must
  the scripts and test files named.
* ``text`` (output) and ``yaml`` are not run.  A block without a language fails.

The simulator's parameter table in docs/parameters.md (generated from its Spec table: ``python
test/test_docs.py`` rewrites it) and the README's tables of its topics and services and of the
motions' parameters are compared with the nodes themselves.
"""

import ast
import importlib
import os
from pathlib import Path
import re
import shlex
import signal
import subprocess
import sys

from motion_challenges.motion_fleet import motion_classes
from motion_challenges.motion_fleet import MotionFleet
import pytest
from rclpy.parameter import Parameter
from sim_diffdrive import harness
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.parameters import live_parameters
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.sim.node import PARAMETERS
from sim_diffdrive.sim.node import UnicycleSim
import yaml

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
PARAMETER_PAGE = ROOT / 'docs' / 'parameters.md'
PAGES = [README, ROOT / 'CONTRIBUTING.md', *sorted((ROOT / 'docs').glob('*.md'))]
LANGUAGES = {'python', 'bash', 'console', 'text', 'yaml'}
TABLE_START = '<!-- generated from sim_diffdrive.sim.node.PARAMETERS: python test/test_docs.py -->'
TABLE_END = '<!-- end of the generated table -->'
BUILT_IN = {'use_sim_time', 'start_type_description_service'}
# Parameters that open something (a port, a file): checked by their Spec, built as off.
OPENS = {'foxglove_port': '0', 'view_port': '0', 'record_file': "''"}
FENCE = re.compile(r'^( *)```(\S*)\s*$')


# -- the pages ----------------------------------------------------------------------------

def blocks(page):
    """Return (page, line, language, text, the last non-blank line before it) per block."""
    lines = page.read_text().splitlines()
    found, i = [], 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if not match:
            i += 1
            continue
        indent = len(match.group(1))
        end = next((j for j in range(i + 1, len(lines)) if lines[j].strip() == '```'), None)
        assert end is not None, f'{page.name}:{i + 1}: the block is never closed'
        text = ''.join(line[indent:] + '\n' for line in lines[i + 1:end])
        before = next((lines[j].strip() for j in range(i - 1, -1, -1) if lines[j].strip()), '')
        found.append((page, i + 1, match.group(2), text, before))
        i = end + 1
    return found


BLOCKS = [block for page in PAGES for block in blocks(page)]


def where(block):
    return f'{block[0].relative_to(ROOT)}:{block[1]}'


def section(text, title):
    """Return the part of a page under the heading that starts with title."""
    match = re.search(rf'^## {re.escape(title)}.*?$(.*?)(?=^## |\Z)', text, re.M | re.S)
    assert match, f'no section {title!r}'
    return match.group(1)


def console_scripts():
    text = (ROOT / 'setup.py').read_text()
    return set(re.findall(r"'(\w+) = [\w.]+:\w+'", text))


def launch_file():
    """Return the launch file's declared arguments and its MOTIONS."""
    tree = ast.parse((ROOT / 'launch' / 'unicycle.launch.py').read_text())
    declared = {node.args[0].value for node in ast.walk(tree) if isinstance(node, ast.Call)
                and getattr(node.func, 'id', None) == 'DeclareLaunchArgument'}
    motions = next(ast.literal_eval(node.value) for node in tree.body
                   if isinstance(node, ast.Assign) and node.targets[0].id == 'MOTIONS')
    return declared, set(motions)


# -- the executables, built as they start ------------------------------------------------

def build(executable, context):
    if executable == 'unicycle_sim':
        return [UnicycleSim(context=context)]
    if executable == 'motion_fleet':
        fleet = MotionFleet(context=context)
        try:
            return [fleet, *fleet.build()]
        except BaseException:
            fleet.destroy_node()
            raise
    return [motion_classes()[executable](context=context)]


def started(executable, ros_args=()):
    """Build executable from ros_args; return {parameter: value} and the live ones."""
    with held_context(['example', '--ros-args', *ros_args],
                      int(os.environ['ROS_DOMAIN_ID'])) as context:
        nodes = []
        try:
            nodes = build(executable, context)
            values, live = {}, set()
            for node in nodes:
                for name in node.list_parameters([], 0).names:
                    values.setdefault(name, node.get_parameter(name).value)
                live |= live_parameters(node)
            return values, live
        finally:
            for node in nodes:
                node.destroy_node()


def check_ros_args(executable, args):
    """Return what is wrong with running executable with args (the words after it)."""
    if executable not in console_scripts():
        return [f'{executable} is not an executable of this package']
    if args and args[0] != '--ros-args':
        return [f'{executable} takes no arguments before --ros-args: {args}']
    args, given, problems = list(args[1:]), [], []
    specs = {spec.name: spec for spec in PARAMETERS}
    for i, arg in enumerate(args[:-1]):
        if arg in ('-p', '--param'):
            name, _, value = args[i + 1].partition(':=')
            given.append(name)
            if name in OPENS and executable == 'unicycle_sim':
                try:
                    specs[name].check(yaml.safe_load(value))
                except ParameterError as error:
                    problems.append(str(error))
                args[i + 1] = f'{name}:={OPENS[name]}'
        elif arg == '--params-file':
            path = Path(args[i + 1])
            args[i + 1] = str(path if path.is_absolute() else ROOT / path)
            if not Path(args[i + 1]).is_file():
                problems.append(f'no params file {args[i + 1]}')
    if problems:
        return problems
    try:
        declared = started(executable, args)[0]
    except Exception as error:  # what the user would see instead of a running node
        return [f'{executable} refuses to start: {error}']
    return [f'{executable} has no parameter {name!r}' for name in given
            if name not in declared]


def check_command(words, output=''):
    """Return what is wrong with one documented command (a list of words)."""
    while words and re.fullmatch(r'\w+=.*', words[0]):
        words = words[1:]  # NAME=value before the command
    if not words:
        return []
    head, args = words[0], words[1:]
    if head == 'ros2' and args[:2] == ['run', 'motion_challenges']:
        return check_ros_args(args[2], args[3:])
    if head == 'ros2' and args[:2] == ['launch', 'motion_challenges']:
        declared, motions = launch_file()
        problems = [] if args[2] == 'unicycle.launch.py' else [f'no launch file {args[2]}']
        for name, _, value in (arg.partition(':=') for arg in args[3:] if ':=' in arg):
            if name not in declared:
                problems.append(f'the launch file has no argument {name!r}')
            elif name == 'motion' and value not in motions:
                problems.append(f'the launch file cannot run {value!r}')
        return problems
    if head == 'ros2' and args[:1] == ['param'] and args[1] in ('set', 'get', 'describe'):
        values, live = started(args[2].rsplit('/', 1)[-1])
        if args[3] not in values:
            return [f'{args[2]} has no parameter {args[3]!r}']
        if 'successful' in output and args[3] not in live:
            return [f'{args[3]} is shown changing but is read-only']
        if 'read-only' in output and args[3] in live:
            return [f'{args[3]} is shown read-only but is live']
        return []
    if head in console_scripts():
        return check_ros_args(head, args)
    if head == 'make':
        targets = set(re.findall(r'^([\w-]+):', (ROOT / 'Makefile').read_text(), re.M))
        return [f'no make target {arg!r}' for arg in args if arg not in targets]
    if head in ('python', 'python3'):
        files = [arg.split('::')[0] for arg in args if arg.endswith('.py') or '.py::' in arg]
        return [f'no file {name}' for name in files if not (ROOT / name).exists()]
    return []


def commands():
    """Yield (block, words, the output shown after it) for each command in the pages."""
    prefix = '$(ros2 pkg prefix motion_challenges)/share/motion_challenges'
    for block in BLOCKS:
        run_with = re.fullmatch(r'<!-- run with: (.+) -->', block[4])
        pairs = [[run_with.group(1), '']] if run_with else []
        if block[2] == 'bash':
            pairs += [[line, ''] for line in block[3].replace('\\\n', ' ').splitlines()]
        elif block[2] == 'console':
            for line in block[3].splitlines():
                if line.startswith('$ '):
                    pairs.append([line[2:], ''])
                elif pairs:
                    pairs[-1][1] += line
        for line, output in pairs:
            lexer = shlex.shlex(line.replace(prefix, str(ROOT)), posix=True,
                                punctuation_chars=True)
            lexer.whitespace_split = True
            words = []
            for word in [*lexer, ';']:
                if word in ('|', '||', '&', '&&', ';'):
                    if words:
                        yield block, words, output
                    words = []
                else:
                    words.append(word)


# -- the tests ----------------------------------------------------------------------------

def test_every_block_says_its_language():
    unknown = [f'{where(block)}: ```{block[2]}' for block in BLOCKS
               if block[2] not in LANGUAGES]
    assert not unknown, f'blocks need one of {sorted(LANGUAGES)}: {unknown}'


def test_every_command_names_what_exists_with_values_it_takes():
    problems = []
    for block, words, output in commands():
        problems += [f'{where(block)}: {" ".join(words)}: {problem}'
                     for problem in check_command(words, output)]
    assert not problems, '\n'.join(problems)


def test_a_wrong_parameter_fails_the_check():
    assert check_command(['unicycle_sim', '--ros-args', '-p', 'rate_hz:=50.0']) == []
    assert check_command(['unicycle_sim', '--ros-args', '-p', 'rate:=50.0']) == [
        "unicycle_sim has no parameter 'rate'"]
    assert 'refuses to start' in check_command(
        ['ros2', 'run', 'motion_challenges', 'rotate_robot', '--ros-args', '-p', 'mode:=fast'])[0]
    assert check_command(['ros2', 'launch', 'motion_challenges', 'unicycle.launch.py',
                          'speed:=2'])


FAST_DDS_LOG = re.compile(r'\[RTPS_\w+ (Error|Warning)\]')
PYTHON = [block for block in BLOCKS if block[2] == 'python'
          and block[4] != '<!-- sim_graph example -->']


@pytest.mark.parametrize('index', range(len(PYTHON)), ids=[where(b) for b in PYTHON])
def test_python_examples_run(index, procs, tmp_path):
    block = PYTHON[index]
    run_with = re.fullmatch(r'<!-- run with: (.+) -->', block[4])
    host = procs('run_with', *shlex.split(run_with.group(1))) if run_with else None
    result = subprocess.run([sys.executable, '-c', block[3]], cwd=tmp_path, text=True,
                            capture_output=True, timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr + (
        host.describe() if host else '')
    following = BLOCKS[BLOCKS.index(block) + 1:]
    if following and following[0][4] == '<!-- output -->':
        # Fast DDS logs to stdout too: a shared-memory port taken by another process at the
        # same moment is an error line, after which it picks another port.
        printed = [line for line in result.stdout.splitlines(keepends=True)
                   if not FAST_DDS_LOG.search(re.sub(r'\x1b\[[0-9;]*m', '', line))]
        assert ''.join(printed) == following[0][3]


def test_the_lockstep_example_stopped_with_ctrl_c_stops_the_robot_and_says_goodbye(procs, graph):
    # Under rclpy's own SIGINT handler the example's goodbye could not go (the simulator held
    # the clock lockstep_timeout), and a call that Ctrl-C interrupted raised RCLError, 2 of 4;
    # a KeyboardInterrupt raised inside rclpy came out as RuntimeError, 1 run in 4.
    block = next(block for block in PYTHON if 'take_part(self)' in block[3])
    # Real time: 3 s of it; cmd_vel_timeout 0: only the example's last stop stops the robot.
    sim = procs('sim', 'unicycle_sim', '--ros-args', '-p', 'publish_clock:=true', '-p',
                'cmd_vel_timeout:=0.0')
    probe = graph.probe(use_sim_time=False)
    example = harness.start_python(block[3])
    try:
        assert graph.spin_until(lambda: probe.moving, 30.0), example.describe() + sim.describe()
        example.send(signal.SIGINT)
        assert example.wait(20.0) == 0, example.describe()
    finally:
        example.kill()
    assert 'Traceback' not in example.output() and 'Drove' not in example.output()
    assert graph.spin_until(lambda: not probe.moving, 5.0)
    assert graph.spin_until(lambda: 'Lockstep: /drive_one_metre left at' in sim.output(), 5.0)
    assert 'going on without' not in sim.output(), sim.describe()


def test_every_link_and_named_file_exists():
    missing = []
    for page in PAGES:
        text = page.read_text()
        for target in re.findall(r'\]\(([^)\s]+)\)', text):
            if re.match(r'\w+:', target):
                continue  # a web address
            path, _, anchor = target.partition('#')
            path = (page.parent / path).resolve() if path else page
            if not path.exists():
                missing.append(f'{page.name}: link {target}')
            elif anchor and anchor not in anchors(path):
                missing.append(f'{page.name}: no heading for {target}')
        for name in re.findall(r'`((?:docs|test|tools|config|launch|rviz|sim_diffdrive|'
                               r'motion_challenges)/[\w./-]*)`', text):
            if not (ROOT / name).exists():
                missing.append(f'{page.name}: `{name}`')
    assert not missing, '\n'.join(missing)


def anchors(page):
    headings = re.findall(r'^#+ (.+)$', page.read_text(), re.M)
    return {re.sub(r'[^\w\- ]', '', heading.lower()).replace(' ', '-') for heading in headings}


def test_every_python_name_in_the_pages_exists(ros_context):
    graph = SimGraph(context=ros_context)
    missing = []
    try:
        for page in PAGES:
            text = page.read_text()
            for name in set(re.findall(r'`((?:sim_diffdrive|motion_challenges)\.[\w.]+)`', text)):
                if not importable(name):
                    missing.append(f'{page.name}: {name}')
            for attribute in set(re.findall(r'`sim_graph\.(\w+)', text)):
                if not hasattr(graph, attribute):
                    missing.append(f'{page.name}: sim_graph.{attribute}')
    finally:
        graph.close()
    assert not missing, '\n'.join(missing)


def importable(dotted):
    parts = dotted.split('.')
    for split in range(len(parts), 0, -1):
        try:
            thing = importlib.import_module('.'.join(parts[:split]))
        except ImportError:
            continue
        for part in parts[split:]:
            if not hasattr(thing, part):
                return False
            thing = getattr(thing, part)
        return True
    return False


def parameter_table():
    def shown(value):
        if isinstance(value, bool):
            return str(value).lower()
        if isinstance(value, list):
            return '[' + ', '.join(shown(item) for item in value) + ']'
        if isinstance(value, str):
            return value or "''"
        return repr(value)

    def number(value):  # an integer bound as the refusal words it (2147483647, not 2.14748e9)
        if isinstance(value, int):
            return str(value)
        return f'{value:g}'.replace('e+0', 'e').replace('e+', 'e')

    rows = [TABLE_START, '| parameter | default | valid values | meaning |', '|---|---|---|---|']
    for spec in PARAMETERS:
        valid = [f'{spec.length} values'] if spec.length else []
        if spec.high is not None:
            valid.append(f'{"(" if spec.low_open else "["}{number(spec.low)}, '
                         f'{number(spec.high)}]')
        valid += ['one of ' + ', '.join(spec.choices)] if spec.choices else []
        meaning = spec.description.replace('|', r'\|').replace('<', '&lt;')
        rows.append(f'| `{spec.name}`{" **live**" if spec.live else ""} | '
                    f'`{shown(spec.default)}` | {"; ".join(valid)} | {meaning} |')
    return '\n'.join(rows + [TABLE_END])


def page_with_table(text):
    start, end = text.index(TABLE_START), text.index(TABLE_END) + len(TABLE_END)
    return text[:start] + parameter_table() + text[end:]


def test_the_parameter_table_is_the_simulators_spec_table():
    text = PARAMETER_PAGE.read_text()
    assert text == page_with_table(text), 'out of date: run python test/test_docs.py'


def test_the_readme_lists_the_simulators_topics_and_services(ros_context):
    # With a map, so the world's topics are there too.
    sim = UnicycleSim(context=ros_context, parameter_overrides=[
        Parameter('publish_clock', value=True),
        Parameter('map_file', value=str(ROOT / 'maps' / 'room.yaml'))])
    try:
        kinds = [(pub.topic_name, pub.msg_type) for pub in sim.publishers]
        kinds += [(sub.topic_name, sub.msg_type) for sub in sim.subscriptions]
        kinds += [(sim.resolve_service_name(srv.srv_name), srv.srv_type) for srv in sim.services]
    finally:
        sim.destroy_node()
    types = {name: '/'.join([kind.__module__.split('.')[0], kind.__module__.split('.')[1],
                             kind.__name__]) for name, kind in kinds}
    lockstep = {name for name in types if name.startswith('/clock/')}
    rows = re.findall(r'^\| (?:subscribes|publishes|service) \| `([^`]+)` \|(.*)$',
                      section(README.read_text(), 'The simulator'), re.M)
    documented = {('/unicycle_sim/' + name[2:] if name.startswith('~/')
                   else '/' + name.lstrip('/')): row for name, row in rows}
    hidden = {'/parameter_events'} | lockstep | {
        name for name in types if name.startswith('/unicycle_sim/') and 'param' in name
        or name.endswith('get_type_description')}
    assert set(documented) == set(types) - hidden
    for name, row in documented.items():
        assert f'`{types[name]}`' in row, name
    time_page = (ROOT / 'docs' / 'time.md').read_text()
    assert all(f'`{name}`' in time_page for name in lockstep), lockstep


def test_the_readme_lists_each_motions_parameters_with_their_defaults():
    text = section(README.read_text(), 'The motions')
    problems = []
    for motion in motion_classes():
        values = started(motion)[0]
        row = re.search(rf'^\| `{motion}` \|.*\|(.*)\|$', text, re.M)
        assert row, f'no row for {motion}'
        for name, default in re.findall(r'`(\w+)`(?: \((-?\d[\d.]*)(?=[ ,)]))?', row.group(1)):
            if name not in values:
                problems.append(f'{motion} has no parameter {name!r}')
            elif default and float(default) != values[name]:
                problems.append(f'{motion} {name} defaults to {values[name]}, not {default}')
        problems += [f'{motion} {name} is not in the section' for name in values
                     if name not in BUILT_IN and f'`{name}`' not in text]
    assert not problems, '\n'.join(problems)


if __name__ == '__main__':
    PARAMETER_PAGE.write_text(page_with_table(PARAMETER_PAGE.read_text()))
    print(f'docs/{PARAMETER_PAGE.name}: the parameter table is written from '
          'sim_diffdrive.sim.node.PARAMETERS')
