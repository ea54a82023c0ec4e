# Shared by scripts/flagship.sh and scripts/test.sh: create .venv (if needed) and install sms
# with the pinned constraints. Needs only Python >= 3.11 and pip.
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  if ! "$PY" -m venv .venv 2>/dev/null; then
    echo "python -m venv is unavailable; using virtualenv from pip" >&2
    rm -rf .venv
    "$PY" -m pip install --user --quiet virtualenv
    "$PY" -m virtualenv --quiet .venv
  fi
fi
STAMP=.venv/.sms-installed
if [ ! -f "$STAMP" ] || [ pyproject.toml -nt "$STAMP" ] || [ constraints.txt -nt "$STAMP" ]; then
  echo "installing sms and its pinned dependencies into .venv (log: .venv/install.log)" >&2
  if ! { .venv/bin/python -m pip install --upgrade pip && \
         .venv/bin/python -m pip install -c constraints.txt -e ".[test]"; } > .venv/install.log 2>&1; then
    tail -n 30 .venv/install.log >&2
    echo "installation failed (full log: .venv/install.log)" >&2
    exit 2
  fi
  touch "$STAMP"
fi
export PATH="$PWD/.venv/bin:$PATH"

# Compile the numba kernels of the given missions once after an install (`sms warmup`), so that their
# first run does not pause for the compilation; $1 names the stamp, the rest are mission files.
warm_kernels() {
  local stamp=".venv/.sms-warm-$1"
  shift
  if [ ! -f "$stamp" ] || [ "$STAMP" -nt "$stamp" ]; then
    echo "compiling the numba kernels of $# mission(s), once after the install (sms warmup)" >&2
    if .venv/bin/sms warmup "$@" >&2; then
      touch "$stamp"
    else
      echo "the warm-up failed (above): the kernels will compile on their first use instead" >&2
    fi
  fi
}
