#!/usr/bin/env bash
# CI guard of the fast reference missions: `sms run` each one, then `sms check` it against its
# shipped baseline (baselines/<mission>.json) and its requirements; JUnit XML per mission. Then every
# shipped campaign through `sms campaign` and `sms check`. A mission or campaign whose file documents a
# design that fails (a stress case) or a thesis result that does not reproduce is expected to fail exactly
# the requirements listed in EXPECTED_FAIL, and nothing else.
#
#   scripts/ci_missions.sh            run and check (exit 1 when any mission fails its check)
#   scripts/ci_missions.sh --update   run and rewrite the baselines (after an intended change)
#
# Results go to ${SMS_CI_OUT:-results/ci}/<mission>/, JUnit to ${SMS_CI_OUT:-results/ci}/junit/.
source "$(dirname "$0")/_env.sh"
MISSIONS=(hipparcos_geo hipparcos_leo budget_tradeoff demeter_3dof caldera_smallsat astrobee_arm chevallard_chaser caldera_s1_slew caldera_s1_synthesized caldera_s2_arm caldera_s3_slew_arm caldera_eo astrobee_slew_twisting astrobee_slew_backstepping chevallard_deploy_track basilisk_rw_reference pulsar_simple pulsar_fast_transfer pulsar_full vicariotto_s2_docking vicariotto_s3a_free_floating vicariotto_s3b_inertia_shaping vicariotto_s3c_free_flying vicariotto_s3d_hierarchical vicariotto_s4_relative_free_flying vicariotto_s6_relative_hil vicariotto_s6_thrusters caldera_capture_tumbling)
declare -A EXPECTED_FAIL=(
  [pulsar_fast_transfer]="joint rate tracking (3.67) below 1e-3 while carrying the tile|wheel rate tracking (3.67) below 1e-3 while carrying the tile|no wheel saturation|base attitude error within the attitude-hold bound"
  [campaign_vicariotto_s3e_laws]="hierarchical ends closer to the attitude than free-flying (S3d)"
  [campaign_astrobee_body_mass]="twisting holds the attitude better with a heavier body (R5)|backstepping holds the attitude better with a heavier body (R5)"
)
# expected_verdicts CHECK.json "name|name": the failing requirements are exactly the expected ones, and
# every baseline metric holds
expected_verdicts() {
  python3 - "$1" "$2" <<'PY'
import json, sys
outcome = json.load(open(sys.argv[1]))
failing = {v["name"] for v in outcome.get("verdicts") or [] if v["status"] != "pass"}
drifting = [d for d in outcome.get("drifts") or [] if d["status"] != "pass"]
expected = {n for n in sys.argv[2].split("|") if n}
for v in outcome.get("verdicts") or []:
    print(f"  {v['status']:7s} {v['name']}: {v['message']}")
for d in drifting:
    print(f"  drift   {d['metric']}: {d['message']}")
if failing != expected or drifting or outcome.get("incomplete"):
    print(f"  expected to fail: {sorted(expected) or 'none'}; failing: {sorted(failing) or 'none'}")
    sys.exit(1)
PY
}
OUT="${SMS_CI_OUT:-results/ci}"
UPDATE=0
[ "${1:-}" = "--update" ] && UPDATE=1
mkdir -p "$OUT/junit"
failed=()
for m in "${MISSIONS[@]}"; do
  echo "=== $m"
  set +e
  sms run "missions/$m.yaml" -o "$OUT/$m" --no-progress > "$OUT/$m.run.log" 2>&1
  rc=$?
  set -e
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 1 ]; then   # 1 = requirements not met: reported by the check below
    cat "$OUT/$m.run.log"
    echo "FAIL: sms run $m exited with $rc"
    failed+=("$m")
    continue
  fi
  if [ "$UPDATE" -eq 1 ]; then
    sms check "$OUT/$m" --write-baseline "baselines/$m.json" || true
    continue
  fi
  set +e
  sms check "$OUT/$m" --baseline "baselines/$m.json" --junit "$OUT/junit/$m.xml" --json > "$OUT/$m.check.json"
  set -e
  if ! expected_verdicts "$OUT/$m.check.json" "${EXPECTED_FAIL[$m]:-}"; then
    failed+=("$m")
  fi
done
# Shipped campaigns (sms campaign, then sms check on the campaign's figures). A campaign whose file
# documents a thesis result that does not reproduce is expected to fail exactly those requirements.
CAMPAIGNS=(campaign_caldera_slew campaign_pulsar_dispersions campaign_astrobee_body_mass campaign_astrobee_link_mass campaign_astrobee_ee_mass campaign_ruggiero_laws campaign_vicariotto_s3ab_shaping campaign_vicariotto_s3e_laws)
if [ "$UPDATE" -eq 0 ]; then
  for c in "${CAMPAIGNS[@]}"; do
    echo "=== $c"
    set +e
    sms campaign "missions/$c.yaml" -o "$OUT/$c" --restart --no-progress > "$OUT/$c.campaign.log" 2>&1
    rc=$?
    set -e
    if [ "$rc" -ne 0 ] && [ "$rc" -ne 1 ]; then
      cat "$OUT/$c.campaign.log"
      echo "FAIL: sms campaign $c exited with $rc"
      failed+=("$c")
      continue
    fi
    set +e
    sms check "$OUT/$c" --junit "$OUT/junit/$c.xml" --json > "$OUT/$c.check.json"
    set -e
    if ! expected_verdicts "$OUT/$c.check.json" "${EXPECTED_FAIL[$c]:-}"; then
      failed+=("$c")
    fi
  done
fi
if [ "${#failed[@]}" -ne 0 ]; then
  echo "missions failing their checks: ${failed[*]}"
  exit 1
fi
echo "all ${#MISSIONS[@]} missions hold their baselines and give their expected verdicts; so do all ${#CAMPAIGNS[@]} campaigns"
