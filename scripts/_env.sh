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
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -c constraints.txt -e ".[test]"
  touch "$STAMP"
fi
export PATH="$PWD/.venv/bin:$PATH"
