# Two commands on a fresh machine: `make test` and `make demo`.
#
# Both create .venv/ with the ROS 2 Jazzy wheels from PyPI and this package installed into it,
# unless ROS 2 Jazzy is already sourced (ROS_DISTRO=jazzy), in which case its rclpy is used.
# Afterwards `. .venv/bin/activate` gives a shell where rclpy works, the executables are on
# PATH and discovery stays on this machine.

SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

# The Jazzy builds of the ROS wheels (the lower of the two versions PyPI lists for each).
ROS_WHEELS := ros-rclpy==7.1.6 ros-geometry-msgs==5.3.6 ros-nav-msgs==5.3.6 \
	ros-std-srvs==5.3.6 ros-sensor-msgs==5.3.6 ros-rosgraph-msgs==2.0.3 ros-rmw-fastrtps-cpp==8.4.3 \
	ros-ament-index-python==1.8.1
# The linters' own dependencies come with ament_flake8/ament_pep257 from apt, not with the wheels:
# these are the versions Ubuntu 24.04 (Jazzy's platform) ships.
ROS_TEST_WHEELS := ros-ament-flake8==0.17.3 ros-ament-pep257==0.17.3 \
	flake8==7.0.0 flake8-builtins==2.1.0 flake8-comprehensions==3.14.0 \
	flake8-docstrings==1.7.0 flake8-import-order==0.19.2 flake8-quotes==3.3.2 pydocstyle==6.3.0
# pillow: map_server's PGM/PNG map images (map_file).
# rerun-sdk: view_port's browser view (its wheel carries the rerun program and the web viewer);
# playwright drives the system's Chromium in test_view.py (no browser download).
PY_DEPS := numpy pillow pytest pytest-xdist hypothesis colcon-common-extensions matplotlib import-linter \
	mcap mcap-ros2-support foxglove-sdk websockets rerun-sdk==0.41.0 playwright==1.65.2

.PHONY: venv test demo bench stress lint clean

venv: $(STAMP)

$(STAMP): Makefile setup.py package.xml tools/setup_venv.sh tools/build_tf2_msgs.py \
		tools/interfaces/tf2_msgs/msg/TFMessage.msg
	PYTHON=$(PYTHON) VENV=$(VENV) ROS_WHEELS="$(ROS_WHEELS)" \
		ROS_TEST_WHEELS="$(ROS_TEST_WHEELS)" PY_DEPS="$(PY_DEPS)" bash tools/setup_venv.sh
	touch $@

# Bytecode first: an editable install leaves it to the first import, which writes none when
# PYTHONDONTWRITEBYTECODE is set, and each of the processes the tests start would compile the
# package again (about 0.05 s of CPU each).  pytest keeps its rewritten test modules as bytecode
# too, unless PYTHONDONTWRITEBYTECODE is set: then each worker rewrites all of them again
# (about 2 s of CPU each, every run).  Four workers on two cores: the tests wait for the
# processes they start for a good part of their time (docs/performance.md).  The tests go out
# one at a time, the longest first, those that mostly wait to the last worker, and a module
# fixture's tests to one worker together (test/conftest.py).
test: $(STAMP)
	source $(VENV)/bin/activate && python -m compileall -q motion_challenges sim_diffdrive \
		&& env -u PYTHONDONTWRITEBYTECODE python -m pytest -q -n 4 --dist load --maxschedchunk 1 test

# make demo VIEW=9090: watch every run live at http://127.0.0.1:9090/ (at 2x real time).
demo: $(STAMP)
	source $(VENV)/bin/activate && python tools/demo.py $(if $(VIEW),--view $(VIEW))

bench: $(STAMP)
	source $(VENV)/bin/activate && python tools/bench.py

stress: $(STAMP)
	source $(VENV)/bin/activate && python tools/stress.py

lint: $(STAMP)
	source $(VENV)/bin/activate && python -m pytest -q test/test_flake8.py test/test_pep257.py

clean:
	rm -rf $(VENV) build install log .pytest_cache
