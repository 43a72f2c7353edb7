#!/usr/bin/env bash
# Install vtkvol with its desktop app and open the built-in sample volume.
# Usage: ./scripts/run-app.sh [FILE]
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install -q -e ".[app]"
if [ $# -eq 0 ]; then
  exec vtkvol open --sample
else
  exec vtkvol open "$@"
fi
