#!/usr/bin/env bash
# Set up (first run) and run the whole test suite, slow tests included.
# Extra arguments go to pytest, e.g. scripts/test.sh -m "not slow".
source "$(dirname "$0")/_env.sh"
# The report test renders in headless Chromium (Debian's package); install it when we can
# (root with apt-get), otherwise that test says why it is skipped.
if [ ! -x /usr/bin/chromium ] && command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
  echo "installing Debian's chromium for the report test (log: .venv/chromium-install.log)" >&2
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; } > .venv/chromium-install.log 2>&1 \
    || echo "could not install chromium (see .venv/chromium-install.log): the browser test will be skipped" >&2
fi
exec .venv/bin/python -m pytest "$@"
