#!/usr/bin/env bash
# Set up (first run) and run the flagship mission end to end into results/pulsar_simple/:
# model summary, ΔV budget, workspace/index maps, LMI gains, simulation with its MCAP recording
# (results/pulsar_simple/simulation.mcap), requirement verdicts and the HTML report
# (results/pulsar_simple/report.html, copied to reports/pulsar_simple.html).
source "$(dirname "$0")/_env.sh"
MISSION="${1:-missions/pulsar_simple.yaml}"
NAME="$(basename "$MISSION" .yaml)"
OUT="results/$NAME"
warm_kernels "$NAME" "$MISSION"
set +e
sms run "$MISSION" --out "$OUT"
rc=$?
set -e
if [ -f "$OUT/report.html" ]; then
  mkdir -p reports
  cp "$OUT/report.html" "reports/$NAME.html"
  echo "report: reports/$NAME.html"
fi
exit $rc
