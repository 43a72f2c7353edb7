#!/usr/bin/env bash
# Install vtkvol with its desktop app and open the built-in sample volume.
# Usage: ./scripts/run-app.sh [FILE]
# Installs into the active virtual/conda environment, else into .venv in the checkout
# (created on first use); never into the system's Python.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/project-env.sh
. scripts/project-env.sh

# Qt's xcb platform plugin loads these; Mesa gives OpenGL where there is no GPU driver.
PACKAGES="libegl1 libgl1 libgl1-mesa-dri libglu1-mesa libxkbcommon-x11-0 libxcb-cursor0
  libxcb-icccm4 libxcb-keysyms1 libxcb-shape0 libxcb-xinerama0 libxcb-image0
  libxcb-render-util0 libxcb-randr0 libdbus-1-3 libfontconfig1"
# shellcheck disable=SC2086
vtkvol_apt_install $PACKAGES || true  # not Debian: the system's own Qt dependencies apply

vtkvol_env_install app
if [ "$VTKVOL_BIN" = "$VTKVOL_VENV/bin" ]; then
  vtkvol_say "later, run vtkvol as $VTKVOL_BIN/vtkvol, or after: source .venv/bin/activate"
fi
if [ $# -eq 0 ]; then
  exec "$VTKVOL_BIN/vtkvol" open --sample
else
  exec "$VTKVOL_BIN/vtkvol" open "$@"
fi
