# Sourced by test.sh and run-app.sh: choose the Python environment vtkvol is installed into, and
# install it there. Never installs into the system's or the user's global Python.
#
#   an active virtual environment ($VIRTUAL_ENV)    used as it is
#   an active conda environment ($CONDA_PREFIX)     used as it is
#   otherwise                                       .venv in the checkout, created on first use
#
# After `vtkvol_env_install EXTRA`, $VTKVOL_PY is the environment's interpreter and
# $VTKVOL_BIN its folder of commands (vtkvol, pytest, ruff).

vtkvol_say() { echo "vtkvol setup: $*" >&2; }
vtkvol_fail() { echo "vtkvol setup: $*" >&2; exit 1; }

VTKVOL_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VTKVOL_VENV="$VTKVOL_ROOT/.venv"

# apt-get install the Debian packages named, through sudo when not root; no-op elsewhere.
vtkvol_apt_install() {
  command -v dpkg >/dev/null 2>&1 || return 1
  local missing="" p
  for p in "$@"; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
  [ -z "$missing" ] && return 0
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  vtkvol_say "installing Debian packages:$missing"
  $sudo apt-get update -qq
  # shellcheck disable=SC2086
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq $missing >/dev/null
}

# Prints "major minor" of the interpreter given, or nothing if it does not run.
vtkvol_py_version() {
  "$1" -c 'import sys; print(sys.version_info[0], sys.version_info[1])' 2>/dev/null
}

# The interpreter to create .venv with: $PYTHON if set, else the first python3 on the PATH,
# else the newest python3.X found. Checks Python >= 3.10.
vtkvol_find_python() {
  local candidates="${PYTHON:-} python3 python3.13 python3.12 python3.11 python3.10 python"
  local c path version
  for c in $candidates; do
    path="$(command -v "$c" 2>/dev/null)" || continue
    version="$(vtkvol_py_version "$path")" || continue
    [ -n "$version" ] || continue
    set -- $version
    if [ "$1" -eq 3 ] && [ "$2" -ge 10 ]; then
      echo "$path"
      return 0
    fi
    vtkvol_say "skipping $path: Python $1.$2 (vtkvol needs Python >= 3.10)"
  done
  return 1
}

vtkvol_create_venv() {
  local python
  python="$(vtkvol_find_python)" ||
    vtkvol_fail "no Python >= 3.10 found on the PATH (set PYTHON=/path/to/python3.10+ to name one)"
  local version
  version="$("$python" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')"
  vtkvol_say "creating $VTKVOL_VENV with $python (Python $version)"
  if ! "$python" -m venv "$VTKVOL_VENV" >/dev/null 2>&1; then
    # Debian and Ubuntu ship venv's ensurepip (and pip) in packages of their own.
    rm -rf "$VTKVOL_VENV"
    vtkvol_apt_install python3-venv python3-pip "python$version-venv" ||
      vtkvol_fail "$python cannot create a virtual environment (python -m venv failed)"
    "$python" -m venv "$VTKVOL_VENV" ||
      { rm -rf "$VTKVOL_VENV"; vtkvol_fail "$python -m venv failed even with python3-venv"; }
  fi
}

# Chooses the environment (creating .venv when needed) and sets VTKVOL_PY / VTKVOL_BIN.
vtkvol_env_select() {
  if [ -n "${VIRTUAL_ENV:-}" ] && [ -x "$VIRTUAL_ENV/bin/python" ]; then
    VTKVOL_PY="$VIRTUAL_ENV/bin/python"
  elif [ -n "${CONDA_PREFIX:-}" ] && [ -x "$CONDA_PREFIX/bin/python" ]; then
    VTKVOL_PY="$CONDA_PREFIX/bin/python"
  else
    # A .venv whose interpreter no longer runs (its Python was removed or upgraded) is remade.
    if [ -d "$VTKVOL_VENV" ] && [ -z "$(vtkvol_py_version "$VTKVOL_VENV/bin/python")" ]; then
      vtkvol_say "$VTKVOL_VENV no longer runs; making it again"
      rm -rf "$VTKVOL_VENV"
    fi
    [ -d "$VTKVOL_VENV" ] || vtkvol_create_venv
    VTKVOL_PY="$VTKVOL_VENV/bin/python"
  fi
  local version
  version="$(vtkvol_py_version "$VTKVOL_PY")"
  set -- $version
  if [ "${1:-0}" -ne 3 ] || [ "${2:-0}" -lt 10 ]; then
    vtkvol_fail "the active environment's Python ($VTKVOL_PY) is ${1:-?}.${2:-?}; vtkvol needs >= 3.10"
  fi
  VTKVOL_BIN="$(dirname "$VTKVOL_PY")"
  export VTKVOL_PY VTKVOL_BIN
}

# Installs vtkvol (editable) with the extra given into the chosen environment. A second run
# with the same pyproject.toml/setup.py and the same extra installs nothing and takes a second.
vtkvol_env_install() {
  local extra="$1"
  vtkvol_env_select
  local prefix key
  prefix="$(dirname "$VTKVOL_BIN")"
  key="$(cat "$VTKVOL_ROOT/pyproject.toml" "$VTKVOL_ROOT/setup.py" | cksum | cut -d' ' -f1)"
  key="$key $VTKVOL_ROOT compat"
  local stamp="$prefix/.vtkvol-installed-$extra"
  if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$key" ] &&
     "$VTKVOL_PY" -c 'import vtkvol' >/dev/null 2>&1; then
    return 0
  fi
  vtkvol_say "installing vtkvol[$extra] into $(dirname "$VTKVOL_BIN") (a few minutes the first time)"
  # compat: the editable install is the checkout's root on sys.path (a .pth line), not an
  # import finder that runs after the path search — with a finder, Python started in the
  # folder that holds a clone named vtkvol took the clone's root for an empty namespace
  # package (issue 21). vtkvol/__init__.py finds ui/, plugins/ and resources/ from there.
  "$VTKVOL_PY" -m pip install -q -e "$VTKVOL_ROOT[$extra]" --config-settings editable_mode=compat
  echo "$key" > "$stamp" 2>/dev/null || true  # a read-only environment reinstalls each time
}
