#!/usr/bin/env bash
# Regenerate the project's docs/benchmarks.* (and charts) from this checkout, with the small real
# stacks of ../shared/data. `vtkvol bench` itself needs no checkout: users run it with their own
# output folder and data. Usage: ./scripts/benchmarks.sh [--quick] [--size N]
# Then the empty-space skipping measurement (`vtkvol bench --empty-space`) on the bead and
# nuclei stacks, into its own section of the same files.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/project-env.sh
. scripts/project-env.sh
vtkvol_env_install test  # the project's .venv (or the active environment), as test.sh makes it
DATA=../shared/data
args=()
for f in Bead_Image1_crop.tif platynereis_nuclei_labels_256x256x103.tif \
         DeconvolutionSampleVerticalGrid1AU-crop.tif; do
  if [ -f "$DATA/$f" ]; then args+=(--data "$DATA/$f"); fi
done
status=0
"$VTKVOL_BIN/vtkvol" bench -o docs "${args[@]}" "$@" || status=$?  # 1: some setting failed (recorded)
sparse=()
for f in Bead_Image1_crop.tif platynereis_nuclei_labels_256x256x103.tif; do
  if [ -f "$DATA/$f" ]; then sparse+=(--data "$DATA/$f"); fi
done
"$VTKVOL_BIN/vtkvol" bench --empty-space -o docs "${sparse[@]}" "$@" || status=$?
exit "$status"
