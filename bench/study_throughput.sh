#!/bin/sh
# vmsim study on 1 rank (no MPI) and on 2 ranks (mpirun -np 2), interleaved 1, 2, 1, 2, on bench/study_kv.toml.
# Prints each run's wall time, the CPU time of all its processes, and the load average before it.
# Usage: bench/study_throughput.sh [BUILD_DIR] [OUT_DIR]   (defaults: build, /tmp/vmsim_study_bench)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-$here/../build}
out=${2:-/tmp/vmsim_study_bench}
vmsim=$build/app/vmsim
mkdir -p "$out"
for round in 1 2; do
  for np in 1 2; do
    load=$(cut -d' ' -f1-3 /proc/loadavg)
    if [ "$np" = 1 ]; then launch=""; else launch="mpirun -np $np --allow-run-as-root"; fi
    /usr/bin/time -f "%e %U %S %M" -o "$out/time.txt" $launch "$vmsim" study "$here/study_kv.toml" --out "$out/np$np" \
      --keep summary -q
    set -- $(cat "$out/time.txt")
    cpu=$(awk "BEGIN { print $2 + $3 }")
    echo "round $round, $np rank(s): wall $1 s, CPU $cpu s (all processes), peak RSS $4 KB (largest process), load before: $load"
    # every column before cpu_time_s (variation, name, status, the two gains, the figures)
    cut -d, -f1-13 "$out/np$np/results.csv" > "$out/np$np.table"
  done
done
cmp "$out/np1.table" "$out/np2.table" && echo "results.csv: 1 and 2 ranks agree (every column but cpu_time_s)"
