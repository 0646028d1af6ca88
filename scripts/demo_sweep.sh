#!/bin/sh
# The grid sweep behind `make demo`'s setting (docs/results/demo_sweep.json, docs/results.md):
# the paper's four methods and the two reference methods (goal_known, oracle) on simple and
# office, with a periodic human (a push every ΔT = 3 or 10 steps) and a corrective human (pushes
# only when the robot leaves the preferred route, reaction delay 1 step, misses 20% of needs).
# 2 maps x 6 methods x 3 human settings x 5 instances x 6 runs = 1080 grid episodes: 80 s of
# CPU, 2 min 23 s wall here with the default workers. Then: python scripts/results.py (writes
# docs/results.md and the JSON). The committed copy keeps the episodes table only (the per-step
# rows deleted, VACUUM, journal_mode=delete: 1 MB instead of 12 MB).
set -e
DB=${1:-docs/results/demo_sweep.sqlite}
for MAP in simple office; do
  pathpref evaluate --map "$MAP" --methods all reference --delta-t 3 10 --instances 5 --runs 6 \
    --db "$DB" --no-progress > /dev/null
  pathpref evaluate --map "$MAP" --methods all reference --delta-t 1 \
    --push-rule "corrective delay=1 miss=0.2" --instances 5 --runs 6 --db "$DB" --no-progress \
    > /dev/null
done
