#!/usr/bin/env bash
# Install everything the test suite needs on a fresh Debian/Ubuntu machine, then run it.
# Usage: ./scripts/test.sh [pytest args…]
# Installs into the active virtual/conda environment, else into .venv in the checkout
# (created on first use); never into the system's Python.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/project-env.sh
. scripts/project-env.sh

# Qt windows need an X server; the tests start Xvfb themselves (pytest-xvfb). Install the
# Debian packages that are missing (Xvfb, Mesa's EGL/GL, the xcb libraries Qt's platform
# plugin loads).
PACKAGES="xvfb xauth libegl1 libgl1 libgl1-mesa-dri libglu1-mesa libxkbcommon-x11-0
  libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-shape0 libxcb-xinerama0 libxcb-image0
  libxcb-render-util0 libxcb-randr0 libdbus-1-3 libfontconfig1"
if command -v dpkg >/dev/null 2>&1; then
  # shellcheck disable=SC2086
  vtkvol_apt_install $PACKAGES
elif ! command -v Xvfb >/dev/null 2>&1; then
  vtkvol_fail "Xvfb is missing and this is not a Debian-based system: install Xvfb first."
fi

vtkvol_env_install test
"$VTKVOL_PY" -m ruff check .
exec "$VTKVOL_PY" -m pytest "$@"
