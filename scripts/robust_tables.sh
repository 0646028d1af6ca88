#!/usr/bin/env bash
# The robust planner's tables in docs/robust.md. Each block writes one SQLite database
# under results/ (resumable: rerun the script after a crash and finished episodes are skipped)
# and prints its Markdown table. Usage: bash scripts/robust_tables.sh [part ...]
# Parts: csweep simple office classroom warehouse atrium (default: all). Environment: N (sweep
# size flags), HUMANS, PRESETS (e.g. PRESETS=robust to skip the paper preset), SIMPLE_DT, OUT.
set -euo pipefail
PP="${PP:-.venv/bin/pathpref}"
OUT="${OUT:-results}"
N="${N:---instances 6 --runs 20}"
HUMANS="${HUMANS:-map consistent}"
PRESETS="${PRESETS:-paper robust}"
SIMPLE_DT="${SIMPLE_DT:-1 5 10 20 30}"
mkdir -p "$OUT"
parts=("$@"); [ ${#parts[@]} -eq 0 ] && parts=(csweep simple office classroom warehouse atrium)
for part in "${parts[@]}"; do
  case "$part" in
    csweep)
      for c in 0.3 1 3 10 30; do
        $PP evaluate --map simple --preset robust --methods goal_only path_preference \
          --delta-t 5 30 --ucb-c "$c" $N --db "$OUT/csweep_c$c.sqlite" --no-progress
      done ;;
    simple)
      for preset in $PRESETS; do
        $PP evaluate --map simple --preset "$preset" --methods all reference \
          --delta-t $SIMPLE_DT $N --db "$OUT/simple_$preset.sqlite" --no-progress
      done ;;
    office|classroom)
      for preset in $PRESETS; do
        for human in $HUMANS; do
          $PP evaluate --map "$part" --preset "$preset" --human "$human" --methods all reference \
            --delta-t 1 5 $N --db "$OUT/${part}_${preset}_${human}.sqlite" --no-progress
        done
      done ;;
    warehouse|atrium)
      for preset in $PRESETS; do
        $PP evaluate --map "examples/maps/$part.json" --preset "$preset" --human consistent \
          --methods all reference --delta-t 1 5 $N --db "$OUT/${part}_${preset}.sqlite" \
          --no-progress
      done ;;
    *) echo "unknown part '$part'" >&2; exit 2 ;;
  esac
done
