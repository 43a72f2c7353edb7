#!/usr/bin/env bash
# The built wheel works without the checkout (CI runs this after the tests). Builds the wheel
# (`pip wheel --no-deps`, failing on any setuptools warning about packages or the licence),
# installs it with its dependencies into a fresh virtual environment in a temporary folder,
# and from another temporary folder renders the built-in sample at 64 x 64 with every
# installed illumination method. Checks that each image shows the sample (not the
# background alone) and that every method but `local` lights it differently from `local`.
# Usage: ./scripts/check-wheel.sh [WORK_DIR]   (default: a new temporary folder, removed after)
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/project-env.sh
. scripts/project-env.sh
vtkvol_env_select  # the interpreter that builds the wheel and makes the fresh venv

if [ $# -ge 1 ]; then
  work="$1"; mkdir -p "$work"
else
  work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
fi
say() { echo "check-wheel: $*"; }
fail() { echo "check-wheel: $*" >&2; exit 1; }

start=$SECONDS
log="$work/wheel.log"
"$VTKVOL_PY" -m pip wheel --no-deps -v -w "$work/dist" . >"$log" 2>&1 ||
  { cat "$log" >&2; fail "pip wheel failed"; }
if grep -E "BuildBackendWarning|SetuptoolsDeprecationWarning|would be ignored|[Ll]icen[cs]e.*deprecated" \
    "$log" >&2; then
  fail "the build printed the setuptools warnings above"
fi
wheel="$(ls "$work"/dist/vtkvol-*.whl)"
say "built $(basename "$wheel") ($((SECONDS - start)) s)"

# A fresh environment from the base interpreter (not the project's .venv), outside the checkout.
base="$("$VTKVOL_PY" -c 'import sys; print(sys._base_executable)')"
"$base" -m venv "$work/venv"
"$work/venv/bin/python" -m pip install -q "$wheel"
say "installed into $work/venv ($((SECONDS - start)) s)"

mkdir -p "$work/out"
cd "$work/out"  # no checkout on the path: the renders use the installed files only
methods="$("$work/venv/bin/python" -c \
  'from vtkvol.model.techniques import technique_specs; print(" ".join(technique_specs()))')"
[ -n "$methods" ] || fail "the installed package lists no illumination method"
for method in $methods; do
  t=$SECONDS
  "$work/venv/bin/vtkvol" render sample -o "$method.png" --method "$method" --size 64 64 \
    --iterations 2 --time-budget 60 >"$method.log" 2>&1 || { cat "$method.log" >&2; fail "$method: render failed"; }
  say "$method rendered ($((SECONDS - t)) s)"
done

"$work/venv/bin/python" - $methods <<'EOF'
"""Each image shows the sample; each method but local differs from local."""
import sys

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy


def read(name: str) -> np.ndarray:
    reader = vtk.vtkPNGReader()
    reader.SetFileName(f"{name}.png")
    reader.Update()
    image = reader.GetOutput()
    w, h, _ = image.GetDimensions()
    return vtk_to_numpy(image.GetPointData().GetScalars()).reshape(h, w, -1)[..., :3].astype(float)


local = read("local")
bad = []
for method in sys.argv[1:]:
    image = read(method)
    corner = image[0, 0]  # the background colour
    shown = (np.abs(image - corner).max(axis=2) > 20).mean()
    diff = np.abs(image - local).mean()
    print(f"check-wheel: {method}: {image.shape[1]}x{image.shape[0]}, sample covers "
          f"{shown:.0%}, mean |difference to local| {diff:.2f} levels")
    if image.shape[:2] != (64, 64) or shown < 0.05:
        bad.append(f"{method}: the image does not show the sample")
    if method != "local" and diff < 0.5:
        bad.append(f"{method}: the image is the same as local's")
if bad:
    sys.exit("check-wheel: " + "; ".join(bad))
EOF
say "every method renders from the wheel ($((SECONDS - start)) s)"
