#!/bin/sh
# The grid sweep behind `make demo`'s setting (pathpref/apps/demo_sweep.json, shipped in the
# wheel; docs/results.md): the paper's four methods, the two reference methods (goal_known,
# oracle) and hindsight optimisation (Javdani et al. 2018, the baseline from outside the paper)
# on simple and office, with a periodic human (a push every ΔT = 3 or 10 steps) and a
# corrective human (pushes only when the robot leaves the preferred route, reaction delay 1
# step, misses 20% of needs). 2 maps x 7 methods x 3 human settings x 5 instances x 6 runs =
# 1260 grid episodes.
#
#   sh scripts/demo_sweep.sh [DB [PRESET]]
#
# PRESET defaults to the planner's default (pathpref.planning.pomdp.DEFAULT_PRESET), the one
# `pathpref demo` re-runs with; every row of DB stores it, and a DB holding another preset's
# rows is refused (remove it first: one sweep, one preset). Then: python scripts/results.py
# (writes docs/results.md and the JSON, which names this command and the preset). The stored
# database is trimmed to the episodes table at the end (the per-step rows deleted, VACUUM,
# journal_mode=delete: about 1 MB instead of 13 MB) and exported as text,
# docs/results/demo_sweep_keys.tsv (scripts/demo_sweep_keys.py: per cell the number of
# episodes and a digest of their keys, which tests/test_demo_doc.py reads); the repository
# keeps that export and the cells JSON, not the database.
set -e
DB=${1:-docs/results/demo_sweep.sqlite}
PY=${PYTHON:-python}
PRESET=${2:-$($PY -c 'from pathpref.planning.pomdp import DEFAULT_PRESET; print(DEFAULT_PRESET)')}
if [ -e "$DB" ]; then
  $PY - "$DB" "$PRESET" <<'CHECK'
import sqlite3, sys
db, preset = sys.argv[1:]
other = [p for (p,) in sqlite3.connect(db).execute("SELECT DISTINCT preset FROM episodes")
         if p != preset]
if other:
    sys.exit(f"demo_sweep: {db} holds rows of preset {', '.join(other)}, not {preset}; "
             "remove it first (one sweep, one preset)")
CHECK
fi
for MAP in simple office; do
  $PY -m pathpref evaluate --map "$MAP" --preset "$PRESET" --methods all reference baselines \
    --delta-t 3 10 --instances 5 --runs 6 --db "$DB" --no-progress > /dev/null
  $PY -m pathpref evaluate --map "$MAP" --preset "$PRESET" --methods all reference baselines \
    --delta-t 1 --push-rule "corrective delay=1 miss=0.2" --instances 5 --runs 6 --db "$DB" \
    --no-progress > /dev/null
done
$PY - "$DB" <<'TRIM'
import sqlite3, sys
con = sqlite3.connect(sys.argv[1])
for (table,) in con.execute("SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT IN "
                            "('meta', 'episodes')").fetchall():
    con.execute(f"DELETE FROM {table}")
con.commit()
con.execute("VACUUM")
con.execute("PRAGMA journal_mode=delete")
con.close()
TRIM
$PY "$(dirname "$0")/demo_sweep_keys.py" "$DB" docs/results/demo_sweep_keys.tsv
