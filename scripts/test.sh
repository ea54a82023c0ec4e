#!/usr/bin/env bash
# Set up (first run) and run the whole test suite, slow tests included.
# Extra arguments go to pytest, e.g. scripts/test.sh -m "not slow".
source "$(dirname "$0")/_env.sh"
exec .venv/bin/python -m pytest "$@"
