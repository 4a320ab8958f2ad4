#!/usr/bin/env bash
# The paper-budget cells still owed (docs/results/ablation.md), one after another: a cell with a
# summary.json is done and skipped, one begun resumes (from carry/ if its folder is not here).
#   RUNS=/abs/runs carry/queue.sh        (run from a checkout of the code the cells train with)
set -u
carry="$(cd "$(dirname "$0")" && pwd)"
runs="${RUNS:-runs}"
for cell in "paper 13 1" "paper 13 2" "paper 9 0" "paper 9 1" "paper 9 2"; do
  set -- $cell
  name="$1_r$2_s$3"; dir="$runs/$name"
  [ -f "$dir/$1/summary.json" ] && continue
  if [ ! -e "$dir" ] && [ -f "$carry/$name.tar" ]; then "$carry/carry.sh" unpack "$name" "$runs" || exit 1; fi
  resume=(); [ -f "$dir/$1/config.json" ] && resume=(--resume)
  echo "queue: $name ${resume[*]} ($(date -u +%FT%TZ))"
  python -m experiments.ablation --out "$dir" --variants "$1" --ranges "$2" --only-seeds "$3" "${resume[@]}" || exit 1
done
