#!/usr/bin/env bash
# The arm's calibration through the real stack (docs/training.md "The arm's angle sensors"): the nine nodes of
# `lhd up real` with the machine's RLD against the twin, whose device reads the boom and the bucket 2 deg high
# (arm_zero_error_deg [2, 2]): uncalibrated (the bridge's zeros 0), and calibrated (real_machine_zeroed.yaml: the
# zeros at 2 deg, 0.034907 rad); and the device reading true. From the repository root, alone on the machine
# (real time; about 7 min on 2 cores):  bash docs/evidence/arm_offsets/twin/run.sh
set -uo pipefail
E=docs/evidence/arm_offsets/twin
common=(--slopes 15 20 25 30 --episodes 2 --seed 0 --no-record)
.venv/bin/lhd up twin "${common[@]}" --run-dir /tmp/arm_twin_true > $E/true.txt 2>&1
.venv/bin/lhd up twin "${common[@]}" --twin-param "arm_zero_error_deg=[2.0,2.0]" --run-dir /tmp/arm_twin_off \
    > $E/off_uncalibrated.txt 2>&1
.venv/bin/lhd up twin "${common[@]}" --twin-param "arm_zero_error_deg=[2.0,2.0]" \
    --params-file $E/real_machine_zeroed.yaml --run-dir /tmp/arm_twin_zeroed > $E/off_calibrated.txt 2>&1
for r in true off zeroed; do cp /tmp/arm_twin_$r/attempts.csv $E/attempts_$r.csv; done
