#!/usr/bin/env bash
# Carry an unfinished training run from one work session to the next, where the machine (and
# everything git does not hold) may be replaced in between. Not part of the library.
#
#   carry/carry.sh pack RUNS CELL     RUNS/CELL -> carry/CELL.tar: each variant's newest checkpoint,
#                                     config.json, log.txt and train/ (the trainer is paused while
#                                     the archive is written, so the checkpoint is whole)
#   carry/carry.sh unpack CELL RUNS   carry/CELL.tar -> RUNS/CELL, to continue with --resume
#   carry/carry.sh finish RUNS CELL   a finished cell (one variant, its summary.json written) ->
#                                     docs/results/ablation/CELL/: summary, play rows, config, the
#                                     log every 200 updates, every 40th update's training row;
#                                     git rm carry/CELL.tar
#
# A checkpoint is ~12 MB (922 122 weights and Adam's two moments); only the newest one travels.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
usage() { sed -n '2,14p' "$0" >&2; exit 2; }
[ $# -eq 3 ] || usage
case "$1" in
  pack)
    runs="$(cd "$2" && pwd)"; cell="$3"; src="$runs/$cell"; out="$here/$cell.tar"
    [ -d "$src" ] || { echo "carry: no run folder $src" >&2; exit 2; }
    pids="$(pgrep -f -- "--out ($src|$2/$cell)( |\$)" || true)"
    resume() { [ -z "$pids" ] || kill -CONT $pids; }
    trap resume EXIT
    [ -z "$pids" ] || kill -STOP $pids
    paths=()
    for v in "$src"/*/; do
      v="${v%/}"; name="$(basename "$v")"
      newest="$(ls "$v/checkpoints" 2>/dev/null | grep -E '^[0-9]+$' | sort -n | tail -1 || true)"
      [ -n "$newest" ] || { echo "carry: $v has no checkpoint" >&2; exit 2; }
      for f in config.json log.txt train "checkpoints/$newest"; do
        [ -e "$v/$f" ] && paths+=("$cell/$name/$f")
      done
      echo "carry: $cell/$name at update $newest"
    done
    tar cf "$out.tmp" -C "$runs" "${paths[@]}"
    mv "$out.tmp" "$out"
    ls -l "$out"
    ;;
  unpack)
    cell="$2"; runs="$3"; tarball="$here/$cell.tar"
    [ -f "$tarball" ] || { echo "carry: no $tarball" >&2; exit 2; }
    if [ -e "$runs/$cell" ]; then
      echo "carry: $runs/$cell exists; resume it as it is, or move it aside first" >&2; exit 2
    fi
    mkdir -p "$runs"
    tar xf "$tarball" -C "$runs"
    echo "carry: $runs/$cell restored; continue it with the same command and --resume"
    ;;
  finish)
    runs="$2"; cell="$3"; variants=("$runs/$cell"/*/)
    [ ${#variants[@]} -eq 1 ] && [ -d "${variants[0]}" ] || { echo "carry: $runs/$cell must hold one variant folder" >&2; exit 2; }
    v="${variants[0]%/}"
    [ -f "$v/summary.json" ] || { echo "carry: $v has no summary.json: the cell has not finished" >&2; exit 2; }
    dest="$here/../docs/results/ablation/$cell"
    mkdir -p "$dest"
    cp "$v/summary.json" "$v/play.jsonl" "$v/config.json" "$dest/"
    # the log's progress lines every 200 updates (one per 2-update chunk would be ~3 000 lines),
    # every other line (starts, resumptions, compiles, stages) kept
    awk 'match($0, /\] update [0-9]+\//) && substr($0, RSTART + 9, RLENGTH - 10) % 200 { next } { print }' \
      "$v/log.txt" > "$dest/log.txt"
    # every 40th update's training row, the header kept (the whole file is ~330 KB)
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "update") u = i; print; next } $u % 40 == 0' \
      "$v/train/metrics.csv" > "$dest/train_metrics.csv"
    # the archive is obsolete once the cell has finished, even if re-packed since its last commit
    if git -C "$here" ls-files --error-unmatch "$cell.tar" > /dev/null 2>&1; then git -C "$here" rm -q -f "$cell.tar"; fi
    echo "carry: $cell's artefacts in docs/results/ablation/$cell; put its figures on docs/results/ablation.md" \
      "(and RESULTS.md), then commit them with the removed carry/$cell.tar"
    ;;
  *) usage ;;
esac
