#!/usr/bin/env bash
# Install everything the test suite needs on a fresh Debian/Ubuntu machine, then run it.
# Usage: ./scripts/test.sh [pytest args…]
set -euo pipefail
cd "$(dirname "$0")/.."

# Qt windows need an X server; the tests start Xvfb themselves (pytest-xvfb). Install the
# Debian packages that are missing (Xvfb, Mesa's EGL/GL, the xcb libraries Qt's platform
# plugin loads).
PACKAGES="xvfb xauth libegl1 libgl1 libgl1-mesa-dri libglu1-mesa libxkbcommon-x11-0
  libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 libxcb-shape0 libxcb-xinerama0 libxcb-image0
  libxcb-render-util0 libxcb-randr0 libdbus-1-3 libfontconfig1"
if command -v dpkg >/dev/null 2>&1; then
  missing=""
  for p in $PACKAGES; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
  if [ -n "$missing" ]; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    # shellcheck disable=SC2086
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
  fi
elif ! command -v Xvfb >/dev/null 2>&1; then
  echo "Xvfb is missing and this is not a Debian-based system: install Xvfb first." >&2
  exit 1
fi

python3 -m pip install -q -e ".[test]"
python3 -m ruff check .
exec python3 -m pytest "$@"
