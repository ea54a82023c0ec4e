#!/usr/bin/env bash
# Set up (first run) and run the flagship mission end to end into results/pulsar_simple/:
# model summary, ΔV budget, workspace/index maps, gains (LMI), simulation with its MCAP recording.
source "$(dirname "$0")/_env.sh"
MISSION="${1:-missions/pulsar_simple.yaml}"
OUT="results/$(basename "$MISSION" .yaml)"
sms compile "$MISSION" --write --out "$OUT"
sms budget "$MISSION" --out "$OUT"
sms analyze "$MISSION" --out "$OUT"
sms synthesize "$MISSION" --out "$OUT"
sms simulate "$MISSION" --out "$OUT"
echo "results: $OUT/ (results.json, CSV tables, PNG plots, simulation.mcap)"
