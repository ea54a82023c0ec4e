#!/usr/bin/env bash
# Set up (first run) and run the flagship mission end to end into results/pulsar_simple/:
# model summary, ΔV budget, workspace/index maps, LMI gains, simulation with its MCAP recording,
# requirement verdicts and the HTML report (results/pulsar_simple/report.html).
source "$(dirname "$0")/_env.sh"
MISSION="${1:-missions/pulsar_simple.yaml}"
OUT="results/$(basename "$MISSION" .yaml)"
sms run "$MISSION" --out "$OUT"
