#!/bin/sh
# The grid sweep behind `make demo`'s setting (pathpref/apps/demo_sweep.json, shipped in the
# wheel; docs/results.md): the paper's four methods and the two reference methods (goal_known,
# oracle) on simple and office, with a periodic human (a push every ΔT = 3 or 10 steps) and a
# corrective human (pushes only when the robot leaves the preferred route, reaction delay 1
# step, misses 20% of needs). 2 maps x 6 methods x 3 human settings x 5 instances x 6 runs =
# 1080 grid episodes.
#
#   sh scripts/demo_sweep.sh [DB [PRESET]]
#
# PRESET defaults to the planner's default (pathpref.planning.pomdp.DEFAULT_PRESET), the one
# `pathpref demo` re-runs with; every row of DB stores it. Then: python scripts/results.py
# (writes docs/results.md and the JSON, which names this command and the preset). The committed
# copy keeps the episodes table only (the per-step rows deleted, VACUUM, journal_mode=delete).
set -e
DB=${1:-docs/results/demo_sweep.sqlite}
PY=${PYTHON:-python}
PRESET=${2:-$($PY -c 'from pathpref.planning.pomdp import DEFAULT_PRESET; print(DEFAULT_PRESET)')}
for MAP in simple office; do
  $PY -m pathpref evaluate --map "$MAP" --preset "$PRESET" --methods all reference \
    --delta-t 3 10 --instances 5 --runs 6 --db "$DB" --no-progress > /dev/null
  $PY -m pathpref evaluate --map "$MAP" --preset "$PRESET" --methods all reference \
    --delta-t 1 --push-rule "corrective delay=1 miss=0.2" --instances 5 --runs 6 --db "$DB" \
    --no-progress > /dev/null
done
