#!/usr/bin/env bash
# Create the project's virtual environment (called by the Makefile; see its header).
set -euo pipefail

: "${PYTHON:=python3}" "${VENV:=.venv}"

if ! "$PYTHON" -c 'import venv, ensurepip' 2>/dev/null; then
  # Debian and Ubuntu split venv out of the interpreter package.
  echo "Installing python3-venv (Debian/Ubuntu) ..."
  apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null
fi

missing=()
# test_two_hosts.py makes two network namespaces with `ip` (iproute2) and loses packets between
# them with iptables; it skips without them.
command -v ip >/dev/null 2>&1 || missing+=(iproute2)
command -v iptables >/dev/null 2>&1 || [ -x /usr/sbin/iptables ] || missing+=(iptables)
# test_view.py opens the browser view in the system's Chromium (Debian's package), headless.
command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 \
  || missing+=(chromium)
if [ ${#missing[@]} -gt 0 ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "Installing ${missing[*]} (for the two-hosts and browser tests) ..."
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
      apt-get install -y -qq "${missing[@]}" >/dev/null; } \
    || echo "Could not install ${missing[*]}: the tests that need them will be skipped."
fi

if [ "${ROS_DISTRO:-}" = "jazzy" ]; then
  echo "ROS 2 Jazzy is sourced: using its rclpy; the venv sees the system packages."
  "$PYTHON" -m venv --system-site-packages "$VENV"
  ros_wheels=""
else
  "$PYTHON" -m venv "$VENV"
  ros_wheels="$ROS_WHEELS $ROS_TEST_WHEELS"
fi

pip=("$VENV/bin/python" -m pip --disable-pip-version-check -q)
# colcon-core (for the colcon build test) supports setuptools below 80 only.
"${pip[@]}" install --upgrade pip 'setuptools<80' wheel
# shellcheck disable=SC2086
"${pip[@]}" install $ros_wheels $PY_DEPS
"${pip[@]}" install -e .

if [ "${ROS_DISTRO:-}" != "jazzy" ]; then
  # PyPI has no tf2_msgs wheel (the simulator publishes /tf with it): generate and compile
  # TFMessage from tools/interfaces/ with the rosidl generators and headers the wheels brought.
  # With ROS 2 Jazzy sourced, apt's ros-jazzy-tf2-msgs is the one to use.
  "$VENV/bin/python" tools/build_tf2_msgs.py
fi

# Make `. .venv/bin/activate` a shell where rclpy finds its ament index and talks only locally.
if ! grep -q 'motion_challenges environment' "$VENV/bin/activate"; then
  cat >> "$VENV/bin/activate" <<'ACTIVATE'

# motion_challenges environment
if [ "${ROS_DISTRO:-}" != "jazzy" ]; then
  export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
fi
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export RCUTILS_COLORIZED_OUTPUT="${RCUTILS_COLORIZED_OUTPUT:-0}"
ACTIVATE
fi
echo "Ready: . $VENV/bin/activate"
