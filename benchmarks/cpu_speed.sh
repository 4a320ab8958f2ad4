#!/usr/bin/env bash
# Every CPU speed table of docs/results/speed.md in one job, each row appended to
# OUT/cpu_speed.jsonl as it is printed (one object per benchmark, each with its machine, date,
# commit and load average; vs_smax's per-environment progress lines are left out):
# raidjax beside SMAX-3m at 4 096 arenas with 5 and 1 sub-steps (vs_smax.py), the rollout with
# observations and the PT-HR playtest at 1 / 8 / 32 games per arena (env_throughput.py), where a
# decision's time goes (step_profile.py), the XLA cost of one sub-step with either observation
# (step_cost.py), the MA-POCA learner's update (train_throughput.py) and the README's first command.
#
#     bash benchmarks/cpu_speed.sh OUT     # about 7 min on 2 cores; needs jaxmarl (pip install -e ".[jaxmarl]")
set -u
out=${1:?usage: bash benchmarks/cpu_speed.sh OUT}
mkdir -p "$out"
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
py=${PYTHON:-python3}
run() {  # run ARGS...: one benchmark, JSON lines to the jsonl, everything else to the log
    echo "## $*" >>"$out/cpu_speed.log"
    $py "$@" 2>>"$out/cpu_speed.log" | grep --line-buffered '^{"benchmark"' | tee -a "$out/cpu_speed.jsonl"
}
for s in 5 1; do
    run benchmarks/vs_smax.py --arenas 4096 --steps 64 --substeps $s
done
for k in 1 8 32; do
    run benchmarks/env_throughput.py --arenas 4096 --steps 64 --playtest-games 4096 --games-per-arena $k
done
run benchmarks/env_throughput.py --arenas 4096 --steps 64 --substeps 1 --playtest-games 4096 --games-per-arena 8
for s in 5 1; do
    run benchmarks/step_profile.py --arenas 4096 --steps 64 --substeps $s
done
for o in raidjax reference; do
    run benchmarks/step_cost.py --arenas 4096 --observation $o
done
run benchmarks/train_throughput.py --presets cpu --pieces
# The README's first command (compiles included), as a whole process: as a new user runs it (empty
# caches: raidjax's compiled programs and its XLA-flag probe), then again with those caches.
run -c "
import json, os, subprocess, sys, tempfile, time
from raidjax.io import machine
with tempfile.TemporaryDirectory() as cache:
    env = {**os.environ, 'XDG_CACHE_HOME': cache}
    for run in ('fresh caches', 'again'):
        t = time.perf_counter()
        subprocess.run([sys.executable, '-m', 'raidjax.calibrate', '--games', '1000'], check=True,
                       stdout=subprocess.DEVNULL, env=env)
        print(json.dumps({'benchmark': 'first_command', 'command': 'python -m raidjax.calibrate --games 1000',
                          'run': run, 'seconds': round(time.perf_counter() - t, 1), 'machine': machine(load=True)}))
"
