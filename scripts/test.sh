#!/usr/bin/env bash
# Set up (first run) and run the whole test suite, slow tests included.
# Extra arguments go to pytest, e.g. scripts/test.sh -m "not slow".
source "$(dirname "$0")/_env.sh"
# The report tests render in headless Chromium and read the PDF's pages with poppler (pdftotext,
# pdftoppm): Debian's packages, installed when we can (root with apt-get); otherwise those tests say
# why they are skipped.
missing=""
[ -x /usr/bin/chromium ] || missing=" chromium"
command -v pdftoppm >/dev/null 2>&1 || missing="$missing poppler-utils"
if [ -n "$missing" ] && command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
  echo "installing Debian's$missing for the report tests (log: .venv/chromium-install.log)" >&2
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing; } > .venv/chromium-install.log 2>&1 \
    || echo "could not install$missing (see .venv/chromium-install.log): the browser and PDF tests will be skipped" >&2
fi
warm_kernels missions missions/*.yaml
# the slowest tests are listed at the end, to keep the run within its 15-minute budget on 2 cores
exec .venv/bin/python -m pytest --durations=20 "$@"
