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
Build tf2_msgs/msg/TFMessage into a virtual environment that holds the ROS 2 Jazzy wheels.

PyPI has no tf2_msgs wheel, but the venv has the rosidl generators and the headers and
libraries of geometry_msgs, std_msgs and builtin_interfaces.  This script does what
rosidl_generate_interfaces() does in CMake for one message: generate the C structs, the C type
supports (the dispatcher, fastrtps_c and introspection_c) and the Python bindings from
tools/interfaces/tf2_msgs/msg/TFMessage.msg, compile them with the system gcc, and install the
result with the same layout as the ros-geometry-msgs wheel:

    <venv>/include/tf2_msgs/tf2_msgs/msg/...           headers
    <venv>/lib/libtf2_msgs__rosidl_*.so                libraries (rpath $ORIGIN)
    <site-packages>/tf2_msgs/                          Python package and its extension modules
    <venv>/share/tf2_msgs/msg/TFMessage.{msg,idl,json}
    <venv>/share/ament_index/resource_index/{packages,rosidl_interfaces}/tf2_msgs

Usage: ``<venv>/bin/python tools/build_tf2_msgs.py`` (tools/setup_venv.sh calls it when ROS 2
is not sourced; with ROS 2 Jazzy from apt, ros-jazzy-tf2-msgs is used instead).  It takes a few
seconds; the generated sources live in a temporary directory and never in the source tree.
"""

from concurrent.futures import ThreadPoolExecutor
import contextlib
import io
import logging
import os
import pathlib
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time

PACKAGE = 'tf2_msgs'
INTERFACE_DIR = pathlib.Path(__file__).resolve().parent / 'interfaces' / PACKAGE
MESSAGES = ('msg/TFMessage.msg',)
# What TFMessage refers to, directly or through geometry_msgs/TransformStamped.
DEPENDENCIES = ('geometry_msgs', 'std_msgs', 'builtin_interfaces')
TYPESUPPORTS = (
    'rosidl_typesupport_c', 'rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_introspection_c')


def generate(prefix, out):
    """Run the rosidl generators (as `rosidl generate` would) into out/<generator>."""
    # The generators find their templates and the type support list through the ament index.
    os.environ['AMENT_PREFIX_PATH'] = os.pathsep.join(
        p for p in (prefix, os.environ.get('AMENT_PREFIX_PATH')) if p)
    # Each generator wheel also installs an egg-info with the same entry points, so rosidl_cli
    # warns about every one of them twice; the duplicates are identical and harmless.
    logging.getLogger('rosidl_cli.entry_points').setLevel(logging.ERROR)
    # `rosidl generate -t c ...` refuses those duplicates outright, so call the extensions it
    # would load directly.
    from rosidl_generator_c.cli import GenerateC
    from rosidl_generator_py.cli import GeneratePython
    from rosidl_typesupport_c.cli import GenerateCTypesupport
    from rosidl_typesupport_fastrtps_c.cli import GenerateFastRTPSCTypesupport
    from rosidl_typesupport_introspection_c.cli import GenerateIntrospectionCTypesupport

    interface_files = [f'{INTERFACE_DIR}:{m}' for m in MESSAGES]
    include_paths = [str(pathlib.Path(prefix) / 'share' / d) for d in DEPENDENCIES]
    generators = {
        'c': GenerateC, 'typesupport_c': GenerateCTypesupport,
        'typesupport_fastrtps_c': GenerateFastRTPSCTypesupport,
        'typesupport_introspection_c': GenerateIntrospectionCTypesupport,
        'py': GeneratePython,
    }
    chatter = io.StringIO()  # the adapter prints every file it reads and writes
    with contextlib.redirect_stdout(chatter):
        for name, extension in generators.items():
            extension(name).generate(
                PACKAGE, interface_files, include_paths, output_path=out / name)


def install_tree(src, dst, suffixes):
    """Copy the files under src whose names end in one of suffixes to the same places in dst."""
    for path in src.rglob('*'):
        relative = path.relative_to(src)
        # tmp/ holds the generators' intermediate .idl files.
        if path.is_file() and path.name.endswith(suffixes) and relative.parts[0] != 'tmp':
            target = dst / relative
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, target)


def compile_shared(output, sources, libs, rpath, include_dirs, lib_dir):
    """Compile and link sources into one shared object (g++ when any source is C++)."""
    cxx = any(str(s).endswith('.cpp') for s in sources)
    cmd = ['g++', '-std=c++17'] if cxx else ['gcc', '-std=c11']
    cmd += ['-O2', '-fPIC', '-shared', '-o', str(output), *map(str, sources)]
    cmd += [f'-I{d}' for d in include_dirs]
    # rpath: find the sibling libraries even without the LD_LIBRARY_PATH that the wheels'
    # bootstrapper sets for Python processes.
    cmd += [f'-L{lib_dir}', f'-Wl,-rpath,{rpath}', *(f'-l{lib}' for lib in libs)]
    result = subprocess.run(cmd, capture_output=True, text=True)
    if result.returncode != 0:
        raise RuntimeError(f'{" ".join(cmd)}\n{result.stderr}')


def build(prefix, gen):
    """Install headers, Python files and interface files, then compile and link everything."""
    prefix = pathlib.Path(prefix)
    include = prefix / 'include' / PACKAGE
    lib_dir = prefix / 'lib'
    site = pathlib.Path(sysconfig.get_paths()['platlib']) / PACKAGE
    share = prefix / 'share' / PACKAGE

    # Headers first: the sources include them as "tf2_msgs/msg/...", as they would after
    # `colcon build`.
    for name in ('c', 'typesupport_fastrtps_c', 'typesupport_introspection_c'):
        install_tree(gen / name, include / PACKAGE, ('.h', '.hpp'))
    install_tree(gen / 'py', site, ('.py',))
    (site / '__init__.py').touch()
    (share / 'msg').mkdir(parents=True, exist_ok=True)
    for message in MESSAGES:
        stem = pathlib.Path(message).stem
        shutil.copyfile(INTERFACE_DIR / message, share / message)
        shutil.copyfile(gen / 'c' / 'tmp' / 'msg' / f'{stem}.idl', share / 'msg' / f'{stem}.idl')
        shutil.copyfile(gen / 'c' / 'msg' / f'{stem}.json', share / 'msg' / f'{stem}.json')

    import numpy
    # Each wheel keeps its headers in include/<package>/ (ament's layout since Humble); Fast
    # CDR keeps the older include/fastcdr/, so include/ itself is on the path too.
    include_dirs = [*sorted(p for p in (prefix / 'include').iterdir() if p.is_dir()),
                    prefix / 'include', sysconfig.get_paths()['include'], numpy.get_include()]

    def lib(name):
        return f'{PACKAGE}__{name}'

    def so(name):
        return lib_dir / f'lib{lib(name)}.so'

    def sources(name, pattern):
        return sorted((gen / name).glob(pattern))

    runtime = ['rosidl_runtime_c', 'rcutils']
    deps_c = [f'{d}__rosidl_generator_c' for d in DEPENDENCIES]
    libraries = {
        'rosidl_typesupport_c': (
            sources('typesupport_c', 'msg/*.cpp'),
            [lib('rosidl_generator_c'), 'rosidl_typesupport_c', *runtime]),
        'rosidl_typesupport_fastrtps_c': (
            sources('typesupport_fastrtps_c', 'msg/detail/*.cpp'),
            [lib('rosidl_generator_c'), 'geometry_msgs__rosidl_typesupport_fastrtps_c',
             *deps_c, 'rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_fastrtps_cpp',
             'fastcdr', *runtime]),
        'rosidl_typesupport_introspection_c': (
            sources('typesupport_introspection_c', 'msg/detail/*.c'),
            [lib('rosidl_generator_c'), 'geometry_msgs__rosidl_typesupport_introspection_c',
             *deps_c, *runtime]),
        # The message's conversions to and from Python objects; Python's own symbols resolve
        # when the interpreter loads the extension modules below.
        'rosidl_generator_py': (
            sources('py', 'msg/*_s.c'),
            [lib('rosidl_generator_c'), 'geometry_msgs__rosidl_generator_py', *deps_c, *runtime]),
    }
    compile_args = {'rpath': '$ORIGIN', 'include_dirs': include_dirs, 'lib_dir': lib_dir}
    compile_shared(so('rosidl_generator_c'), sources('c', 'msg/detail/*.c'),
                   [*deps_c, *runtime], **compile_args)
    with ThreadPoolExecutor() as pool:
        for future in [pool.submit(compile_shared, so(name), srcs, libs, **compile_args)
                       for name, (srcs, libs) in libraries.items()]:
            future.result()
        # One extension module per type support, named as rosidl_generator_py's
        # import_type_support() imports them: tf2_msgs.tf2_msgs_s__<typesupport>.
        suffix = sysconfig.get_config_var('EXT_SUFFIX')
        site_rpath = '$ORIGIN/' + os.path.relpath(lib_dir, site)
        modules = [
            pool.submit(
                compile_shared, site / f'{PACKAGE}_s__{ts}{suffix}',
                [gen / 'py' / f'_{PACKAGE}_s.ep.{ts}.c'],
                [lib('rosidl_generator_py'), lib(ts), lib('rosidl_generator_c'), *runtime],
                rpath=site_rpath, include_dirs=include_dirs, lib_dir=lib_dir)
            for ts in TYPESUPPORTS]
        for future in modules:
            future.result()

    # Last, so that the index names tf2_msgs only once it is complete.
    index = prefix / 'share' / 'ament_index' / 'resource_index'
    for resource, content in (
            ('packages', ''),
            ('rosidl_interfaces', ''.join(
                f'{pathlib.Path(m).with_suffix(".idl")}\n{m}\n' for m in MESSAGES)),
            ('package_run_dependencies', ';'.join(
                (*DEPENDENCIES, 'rosidl_default_runtime')))):
        (index / resource).mkdir(parents=True, exist_ok=True)
        (index / resource / PACKAGE).write_text(content)


def main():
    prefix = sys.prefix
    if prefix == sys.base_prefix:
        sys.exit("build_tf2_msgs.py: run it with the virtual environment's python")
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix='tf2_msgs_') as tmp:
        gen = pathlib.Path(tmp)
        generate(prefix, gen)
        build(prefix, gen)
    print(f'tf2_msgs: generated and built in {time.monotonic() - start:.1f} s')


if __name__ == '__main__':
    main()
