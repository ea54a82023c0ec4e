#!/usr/bin/env bash
# CI guard of the fast reference missions: `sms run` each one, then `sms check` it against its
# shipped baseline (baselines/<mission>.json) and its requirements; JUnit XML per mission.
#
#   scripts/ci_missions.sh            run and check (exit 1 when any mission fails its check)
#   scripts/ci_missions.sh --update   run and rewrite the baselines (after an intended change)
#
# Results go to ${SMS_CI_OUT:-results/ci}/<mission>/, JUnit to ${SMS_CI_OUT:-results/ci}/junit/.
source "$(dirname "$0")/_env.sh"
MISSIONS=(hipparcos_geo hipparcos_leo budget_tradeoff demeter_3dof caldera_smallsat astrobee_arm chevallard_chaser caldera_s1_slew caldera_s1_synthesized caldera_s2_arm caldera_s3_slew_arm astrobee_slew_twisting astrobee_slew_backstepping chevallard_deploy_track basilisk_rw_reference pulsar_simple)
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
  if ! sms check "$OUT/$m" --baseline "baselines/$m.json" --junit "$OUT/junit/$m.xml"; then
    failed+=("$m")
  fi
done
if [ "${#failed[@]}" -ne 0 ]; then
  echo "missions failing their checks: ${failed[*]}"
  exit 1
fi
echo "all ${#MISSIONS[@]} missions pass their requirements and baselines"
