#!/usr/bin/env bash
# The speed table on one accelerator, in one short job: raidjax beside SMAX-3m (vs_smax.py) and the
# random-policy rollout + PT-HR playtest (env_throughput.py) at 4 096 / 65 536 / 262 144 arenas,
# then the XLA cost of one sub-step as the accelerator's compiler counts it (step_cost.py).
# Each benchmark runs under its own time limit, so a slow compile costs one row, not the job;
# every row is appended to OUT/gpu_speed.jsonl as it is printed.
#
#     bash benchmarks/gpu_speed.sh OUT      # needs jax with a GPU backend and jaxmarl importable
#     ARENAS="64 128" bash benchmarks/gpu_speed.sh /tmp/x   # other arena counts (a quick check)
set -u
out=${1:?usage: bash benchmarks/gpu_speed.sh OUT}
mkdir -p "$out"
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
py=${PYTHON:-python3}
nvidia-smi -L 2>&1 | tee "$out/gpu_speed.log"
$py -c "import jax; print('jax', jax.__version__, jax.devices())" 2>&1 | tee -a "$out/gpu_speed.log"
run() {  # run SECONDS ARGS...: one benchmark, JSON lines to the jsonl, everything to the log
    local limit=$1; shift
    echo "## $* (limit ${limit}s)" >>"$out/gpu_speed.log"
    timeout "$limit" $py "$@" 2>>"$out/gpu_speed.log" | grep --line-buffered '^{"benchmark"' | tee -a "$out/gpu_speed.jsonl"
}
sizes=${ARENAS:-4096 65536 262144}
run 200 benchmarks/vs_smax.py --arenas $sizes --steps 64 --repeats 2 --rows smax-3m raidjax-per-arena
for n in $sizes; do
    run 100 benchmarks/env_throughput.py --arenas "$n" --steps 64 --repeats 2 --playtest-repeats 2 --playtest-games "$n"
done
run 120 benchmarks/step_cost.py --arenas "${sizes%% *}"
