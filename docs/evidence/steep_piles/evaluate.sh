#!/usr/bin/env bash
# Held-out evaluation of the 10-40 deg study (docs/training.md "Piles of 10-40 deg"), run from the repository
# root as `bash docs/evidence/steep_piles/evaluate.sh [rld|rlc]` (default rld) after
#   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/steep_piles/lhd_params_steep.yaml --out runs/steep_rld
# or for rlc (the one-recipe study's RLC file with the same three changes)
#   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/steep_piles/lhd_params_steep_rlc.yaml --out runs/steep_rlc
# (RLC with the deployment filter, as the nodes run it), or rlc_to_end (2026-11-30: the same RLC file with the
# demonstrations to the last step)
#   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize \
#       --config docs/evidence/steep_piles/lhd_params_steep_rlc_to_end.yaml --out runs/steep_rlc_to_end
# Every seed's final actor (no best checkpoint, no best seed):
#  - lhd report: 120 held-out episodes (seed 2,000,000) per condition, the 5 seeds' mean +- sd and IQM;
#    dense and light gravel and rocky piles are conditions of the same command;
#  - lhd experiment paper per seed, nominal conditions: table (a) every slope of 10-40 deg, both materials,
#    20 attempts a cell, and table (b) the slope-error sweep on 15 and 30 deg piles (zones built from the told
#    slope, as on the machine).
set -euo pipefail
S=${1:-rld}
E=docs/evidence/steep_piles
case $S in rld) F=steep; V=rld ;; rlc) F=steep_rlc; V=rlc ;; rlc_to_end) F=steep_rlc_to_end; V=rlc ;;
  # 2026-11-30: the push-curl teacher's recipe (docs/evidence/told_high_bound), trained with
  #   lhd train --variant rld --seeds 0-4 --jobs 5 --randomize \
  #       --config docs/evidence/told_high_bound/lhd_params_steep_push_curl.yaml --out runs/push_curl_rld
  push_curl_rld) F=steep_push_curl; V=rld; E=docs/evidence/told_high_bound ;;
  # a two-seed pilot only (docs/evidence/told_high_bound/push_curl_high_pilot/): the same with randomization.slope_error_high_share 0.3 (lhd_params_steep_push_curl_high.yaml)
  push_curl_high_rld) F=steep_push_curl_high; V=rld; E=docs/evidence/told_high_bound ;;
  # 2026-11-30, eighteenth session: the push-curl file with training.demo_told_high 7.5 (every episode told 7.5 deg
  # or more too steep a demonstration), or with task.reward_zones_from_pile 1 (the reward's terms on the pile's own
  # zones); neither key is in the hash, so both run on the push-curl file's nominal evaluation file
  told_high_demos_rld) F=steep_push_curl_told_high_demos; V=rld; E=docs/evidence/told_high_bound ;;
  reward_pile_zones_rld) F=steep_push_curl_reward_pile_zones; V=rld; E=docs/evidence/told_high_bound ;;
  # 2026-11-30, nineteenth session: both keys together (lhd_params_steep_push_curl_told_high_demos_pile_zones.yaml),
  # trained as RLD and as RLC (--variant rlc, the same file: runs/told_high_demos_pile_zones_rlc)
  told_high_demos_pile_zones_rld) F=steep_push_curl_told_high_demos_pile_zones; V=rld; E=docs/evidence/told_high_bound ;;
  told_high_demos_pile_zones_rlc) F=steep_push_curl_told_high_demos_pile_zones; V=rlc; E=docs/evidence/told_high_bound ;;
  # and the same with a quarter of the episodes from rest (lhd_params_steep_push_curl_told_high_demos_pile_zones_rest.yaml)
  told_high_demos_pile_zones_rest_rld) F=steep_push_curl_told_high_demos_pile_zones_rest; V=rld; E=docs/evidence/told_high_bound ;;
  # 2026-11-30, twenty-second session: the same file trained as RLC (--variant rlc: runs/told_high_demos_pile_zones_rest_rlc)
  told_high_demos_pile_zones_rest_rlc) F=steep_push_curl_told_high_demos_pile_zones_rest; V=rlc; E=docs/evidence/told_high_bound ;;
  # 2026-11-30, twenty-first session: and the bridge's drift window (randomization.drift_flag_lag_max_s 0.14;
  # lhd_params_steep_push_curl_told_high_demos_pile_zones_rest_driftlag.yaml)
  told_high_demos_pile_zones_rest_driftlag_rld) F=steep_push_curl_told_high_demos_pile_zones_rest_driftlag; V=rld; E=docs/evidence/told_high_bound ;;
  # 2026-12-01, twenty-fourth session: that file with training.demo_drift_confirm 3 (docs/evidence/drift_confirm/
  # lhd_params_drift_confirm3.yaml; runs/drift_confirm3_rld)
  drift_confirm3_rld) F=drift_confirm3; V=rld; E=docs/evidence/drift_confirm ;;
  # 2026-12-01, twenty-fifth session: the same file trained as RLC (--variant rlc: runs/drift_confirm3_rlc)
  drift_confirm3_rlc) F=drift_confirm3; V=rlc; E=docs/evidence/drift_confirm ;;
  # and as RLC with the level push (training.demo_push_curl 0, demo_late_lift 0: lhd_params_drift_confirm3_level_push.yaml;
  # runs/drift_confirm3_level_push_rlc); neither key is in the hash, so it runs on the drift-confirm evaluation file
  drift_confirm3_level_push_rlc) F=drift_confirm3_level_push; V=rlc; E=docs/evidence/drift_confirm ;;
  # 2026-12-01, twenty-sixth session: the RLC file above (steep_rlc) with the slope curriculum on the reward's test
  # (training.slope_curriculum_reward_test 1: docs/evidence/curriculum_reward_test/lhd_params_steep_rlc_reward_test.yaml;
  # runs/steep_rlc_reward_test); not in the hash, so it runs on the steep RLC file's nominal evaluation file
  steep_rlc_reward_test) F=steep_rlc_reward_test; V=rlc; E=docs/evidence/curriculum_reward_test ;;
  # and its two-seed pilot (seeds 0 and 2) with a stronger curriculum (lhd_params_steep_rlc_reward_test_strong.yaml)
  steep_rlc_reward_test_strong) F=steep_rlc_reward_test_strong; V=rlc; E=docs/evidence/curriculum_reward_test ;;
  # 2026-12-01, twenty-seventh session: the reward-test file with training.demo_failing_share 0.5 (an actor's episode
  # on a failing slope bin a demonstration with probability 0.5 x its failure rate: docs/evidence/demo_failing/
  # lhd_params_steep_rlc_demo_failing.yaml; runs/steep_rlc_demo_failing); not in the hash either
  steep_rlc_demo_failing) F=steep_rlc_demo_failing; V=rlc; E=docs/evidence/demo_failing ;;
  # and the same with demo_failing_share 0.8 (lhd_params_steep_rlc_demo_failing08.yaml; seeds 1 and 3 first, 0, 2, 4 on
  # 2026-12-01, twenty-eighth session)
  steep_rlc_demo_failing08) F=steep_rlc_demo_failing08; V=rlc; E=docs/evidence/demo_failing ;;
  # 2026-12-01, twenty-ninth session: those five seeds' final checkpoints each taken on for 60,000 steps with the
  # learning rates falling to a tenth (docs/evidence/settle_stage/lhd_params_settle.yaml; runs/settle_rlc), and the same
  # with the demonstrations to the last step (lhd_params_settle_teach.yaml; runs/settle_teach_rlc):
  #   lhd train --variant rlc --seeds 0-4 --jobs 5 --randomize --steps 360000 --config <file> --out runs/<name> \
  #       --branch-from 'runs/steep_rlc_demo_failing08/seed_{seed}/checkpoint.pt'
  settle_rlc) F=settle; V=rlc; E=docs/evidence/settle_stage ;;
  settle_teach_rlc) F=settle_teach; V=rlc; E=docs/evidence/settle_stage ;;
  # and the settling stage for the five seeds of the dose 0.5 (lhd_params_settle05.yaml; --branch-from
  # 'runs/steep_rlc_demo_failing/seed_{seed}/checkpoint.pt'; runs/settle05_rlc)
  settle05_rlc) F=settle05; V=rlc; E=docs/evidence/settle_stage ;;
  # 2026-12-01, thirtieth session: the dose-0.8 file with r_success only from 28 kg (the mass margin 8 kg, from the
  # start; docs/evidence/margin8/lhd_params_steep_rlc_margin8.yaml; runs/steep_rlc_margin8)
  steep_rlc_margin8) F=steep_rlc_margin8; V=rlc; E=docs/evidence/margin8 ;;
  # and those five seeds' settling stage (lhd_params_settle_margin8.yaml; --branch-from
  # 'runs/steep_rlc_margin8/seed_{seed}/checkpoint.pt' --steps 360000; runs/settle_margin8_rlc)
  settle_margin8_rlc) F=settle_margin8; V=rlc; E=docs/evidence/margin8 ;;
  # 2026-12-01, thirty-first session: the machine RLD's recipe (drift_confirm3) with the same margin 8, trained from the
  # start (docs/evidence/margin8/lhd_params_drift_confirm3_margin8.yaml; runs/drift_confirm3_margin8_rld)
  drift_confirm3_margin8_rld) F=drift_confirm3_margin8; V=rld; E=docs/evidence/margin8 ;;
  # 2026-12-01, thirty-second session: that file trained as RLC in one run of 360,000 steps whose last 60,000 are the
  # settling stage (lhd_params_drift_confirm3_margin8_settle.yaml; runs/drift_confirm3_margin8_settle_rlc)
  drift_confirm3_margin8_settle_rlc) F=drift_confirm3_margin8_settle; V=rlc; E=docs/evidence/margin8 ;;
  # 2026-12-02, thirty-third session: policies/rlc_steep_margin8's recipe with the zones from the estimate and the reward
  # from the pile's zones, settling in one run (lhd_params_steep_rlc_margin8_zones_settle.yaml; runs/steep_rlc_margin8_zones_settle)
  steep_rlc_margin8_zones_settle) F=steep_rlc_margin8_zones_settle; V=rlc; E=docs/evidence/margin8 ;;
  # the machine RLD's file as RLC with the teacher where the actor fails and the curriculum on the reward's test
  # (lhd_params_drift_confirm3_margin8_failing_settle.yaml; runs/drift_confirm3_margin8_failing_settle_rlc|drift_confirm3_margin8_lidar_settle_rlc|drift_confirm3_margin8_teacher_wins_settle_rlc)
  drift_confirm3_margin8_failing_settle_rlc) F=drift_confirm3_margin8_failing_settle; V=rlc; E=docs/evidence/margin8 ;;
  # the same file with half the episodes told the slope within +-1 deg, the LiDAR right
  # (lhd_params_drift_confirm3_margin8_lidar_settle.yaml; runs/drift_confirm3_margin8_lidar_settle_rlc)
  drift_confirm3_margin8_lidar_settle_rlc) F=drift_confirm3_margin8_lidar_settle; V=rlc; E=docs/evidence/margin8 ;;
  # the same file with demonstrations only where the teacher does at least as well as the actor
  # (lhd_params_drift_confirm3_margin8_teacher_wins_settle.yaml; runs/drift_confirm3_margin8_teacher_wins_settle_rlc)
  drift_confirm3_margin8_teacher_wins_settle_rlc) F=drift_confirm3_margin8_teacher_wins_settle; V=rlc; E=docs/evidence/margin8 ;;
  # 2026-12-02, thirty-fifth session: the machine file as RLC with the penalty on the actor's tanh input
  # (docs/evidence/preact/lhd_params_drift_confirm3_margin8_preact_settle.yaml; runs/drift_confirm3_margin8_preact_settle_rlc)
  drift_confirm3_margin8_preact_settle_rlc) F=drift_confirm3_margin8_preact_settle; V=rlc; E=docs/evidence/preact ;;
  # ... and with the demonstrations' own returns as a lower bound on the critics' target
  # (docs/evidence/preact/lhd_params_drift_confirm3_margin8_preact_bound_settle.yaml; runs/drift_confirm3_margin8_preact_bound_settle_rlc)
  drift_confirm3_margin8_preact_bound_settle_rlc) F=drift_confirm3_margin8_preact_bound_settle; V=rlc; E=docs/evidence/preact ;;
  # ... and the bound alone, without the penalty (lhd_params_drift_confirm3_margin8_bound_settle.yaml; runs/drift_confirm3_margin8_bound_settle_rlc)
  drift_confirm3_margin8_bound_settle_rlc) F=drift_confirm3_margin8_bound_settle; V=rlc; E=docs/evidence/preact ;;
  # ... and five more seeds (5-9) of the penalty and the bound (runs/drift_confirm3_margin8_preact_bound_settle_rlc_rep)
  drift_confirm3_margin8_preact_bound_settle_rlc_rep) F=drift_confirm3_margin8_preact_bound_settle; V=rlc; E=docs/evidence/preact ;;
  # 2026-12-02, thirty-sixth session: the machine RLD's file with the penalty and the bound, trained as RLD, no settling stage
  # (docs/evidence/preact/lhd_params_drift_confirm3_margin8_preact_bound_rld.yaml; runs/drift_confirm3_margin8_preact_bound_rld)
  drift_confirm3_margin8_preact_bound_rld) F=drift_confirm3_margin8_preact_bound_rld; V=rld; E=docs/evidence/preact ;;
  # 2026-12-02, thirty-seventh session: the machine RLD's file (margin 8) on the simulator with the loader fill factor
  # (docs/evidence/fill/lhd_params_drift_confirm3_margin8_fill.yaml; runs/fill_margin8_rld)
  fill_margin8_rld) F=drift_confirm3_margin8_fill; V=rld; E=docs/evidence/fill ;;
  # the recipe of policies/rlc_drift_confirm_margin8 on the same simulator
  # (docs/evidence/fill/lhd_params_drift_confirm3_margin8_preact_bound_settle_fill.yaml; runs/fill_margin8_preact_bound_settle_rlc)
  fill_margin8_preact_bound_settle_rlc) F=drift_confirm3_margin8_preact_bound_settle_fill; V=rlc; E=docs/evidence/fill ;;
  *) echo "usage: evaluate.sh [rld|rlc|rlc_to_end|push_curl_rld|push_curl_high_rld|told_high_demos_rld|reward_pile_zones_rld|told_high_demos_pile_zones_rld|told_high_demos_pile_zones_rlc|told_high_demos_pile_zones_rest_rld|told_high_demos_pile_zones_rest_rlc|told_high_demos_pile_zones_rest_driftlag_rld|drift_confirm3_rld|drift_confirm3_rlc|drift_confirm3_level_push_rlc|steep_rlc_reward_test|steep_rlc_reward_test_strong|steep_rlc_demo_failing|steep_rlc_demo_failing08|settle_rlc|settle_teach_rlc|settle05_rlc|steep_rlc_margin8|settle_margin8_rlc|drift_confirm3_margin8_rld|drift_confirm3_margin8_settle_rlc|steep_rlc_margin8_zones_settle|drift_confirm3_margin8_failing_settle_rlc|drift_confirm3_margin8_lidar_settle_rlc|drift_confirm3_margin8_teacher_wins_settle_rlc|drift_confirm3_margin8_preact_settle_rlc|drift_confirm3_margin8_preact_bound_settle_rlc|drift_confirm3_margin8_bound_settle_rlc|drift_confirm3_margin8_preact_bound_settle_rlc_rep|drift_confirm3_margin8_preact_bound_rld|fill_margin8_rld|fill_margin8_preact_bound_settle_rlc]" >&2
     exit 2 ;; esac
CFG=$E/lhd_params_$F.yaml
NOM=$E/lhd_params_${F}_nominal_eval.yaml
case $S in told_high_demos_rld|reward_pile_zones_rld|told_high_demos_pile_zones_rl?) NOM=$E/lhd_params_steep_push_curl_nominal_eval.yaml ;;
  drift_confirm3_level_push_rlc) NOM=$E/lhd_params_drift_confirm3_nominal_eval.yaml ;;
  fill_margin8_preact_bound_settle_rlc) NOM=$E/lhd_params_drift_confirm3_margin8_fill_nominal_eval.yaml ;;
  drift_confirm3_margin8_rld|drift_confirm3_margin8_settle_rlc|drift_confirm3_margin8_failing_settle_rlc|drift_confirm3_margin8_lidar_settle_rlc|drift_confirm3_margin8_teacher_wins_settle_rlc|drift_confirm3_margin8_preact_settle_rlc|drift_confirm3_margin8_preact_bound_settle_rlc|drift_confirm3_margin8_bound_settle_rlc|drift_confirm3_margin8_preact_bound_settle_rlc_rep|drift_confirm3_margin8_preact_bound_rld) NOM=docs/evidence/drift_confirm/lhd_params_drift_confirm3_nominal_eval.yaml ;;
  steep_rlc_reward_test|steep_rlc_reward_test_strong|steep_rlc_demo_failing|steep_rlc_demo_failing08|settle_rlc|settle_teach_rlc|settle05_rlc|steep_rlc_margin8|settle_margin8_rlc|steep_rlc_margin8_zones_settle) NOM=docs/evidence/steep_piles/lhd_params_steep_rlc_nominal_eval.yaml ;; esac
case $S in push_curl_rld|push_curl_high_rld|told_high_demos_rld|reward_pile_zones_rld|told_high_demos_pile_zones_rl?|told_high_demos_pile_zones_rest_rl?|told_high_demos_pile_zones_rest_driftlag_rld|drift_confirm3_rl?|drift_confirm3_level_push_rlc|steep_rlc_reward_test|steep_rlc_reward_test_strong|steep_rlc_demo_failing|steep_rlc_demo_failing08|settle_rlc|settle_teach_rlc|settle05_rlc|steep_rlc_margin8|settle_margin8_rlc|drift_confirm3_margin8_rld|drift_confirm3_margin8_settle_rlc|steep_rlc_margin8_zones_settle|drift_confirm3_margin8_failing_settle_rlc|drift_confirm3_margin8_lidar_settle_rlc|drift_confirm3_margin8_teacher_wins_settle_rlc|drift_confirm3_margin8_preact_settle_rlc|drift_confirm3_margin8_preact_bound_settle_rlc|drift_confirm3_margin8_bound_settle_rlc|drift_confirm3_margin8_preact_bound_settle_rlc_rep|drift_confirm3_margin8_preact_bound_rld|fill_margin8_rld|fill_margin8_preact_bound_settle_rlc) RUNS=runs/$S; P=$S ;;
  *) RUNS=runs/steep_$S; P=steep_$S ;; esac
# every seed the run has (five for a study, two for a pilot)
SEEDS=$(ls -d $RUNS/seed_*/ | sed "s#.*seed_##; s#/##" | sort -n)
.venv/bin/lhd report $RUNS --held-out nominal,randomized,placement,sensors,delay,light,dense,rocky --config $CFG \
    --jobs 2 --json > $E/${P}_report.json 2> $E/${P}_report.log
for s in $SEEDS; do
  .venv/bin/lhd experiment paper --controllers $V --$V $RUNS/seed_$s/final --config $NOM \
      --slopes 10,15,20,25,30,35,40 --errors=-15,-10,-5,0,5,10,15 --episodes 20 --jobs 2 \
      --out /tmp/${P}_seed$s > /dev/null 2>&1
  mkdir -p $E/${P}_seed$s
  cp /tmp/${P}_seed$s/table_controllers.md /tmp/${P}_seed$s/table_controllers.csv \
     /tmp/${P}_seed$s/table_slope_error.md /tmp/${P}_seed$s/table_slope_error.csv $E/${P}_seed$s/
done
