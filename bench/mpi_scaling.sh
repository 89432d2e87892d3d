#!/usr/bin/env bash
# Strong scaling of a tiled `vmsim run` (app/tiled_run.hpp): the same job on 1 rank and on 2 ranks, interleaved
# (1, 2, 1, 2, ...) so that a changing machine load falls on both alike; one OpenMP thread per rank, so 1 rank uses
# one core and 2 ranks two. Prints per run: wall s, CPU s (user + sys of every process), peak RSS of the largest
# process, and from report.json each rank's removal time, sweeps and peak RSS; then checks that the surfaces are
# identical. Usage: bench/mpi_scaling.sh PATH/TO/vmsim JOB.toml OUTDIR [ROUNDS]
set -euo pipefail
vmsim=${1:?usage: bench/mpi_scaling.sh PATH/TO/vmsim JOB.toml OUTDIR [ROUNDS]}
job=${2:?job}
out=${3:?outdir}
rounds=${4:-2}
mpirun=${MPIRUN:-mpirun}
mkdir -p "$out"
export OMP_NUM_THREADS=1
for r in $(seq 1 "$rounds"); do
  for n in 1 2; do
    dir="$out/r${r}_np$n"
    echo "== round $r, $n rank(s), load $(cut -d' ' -f1 /proc/loadavg)"
    if [ "$n" = 1 ]; then
      /usr/bin/time -f "wall %e s, cpu %U+%S s, peak rss %M KB" "$vmsim" run "$job" --out "$dir" --no-render -q >/dev/null
    else
      /usr/bin/time -f "wall %e s, cpu %U+%S s, peak rss %M KB" \
        "$mpirun" -np "$n" --allow-run-as-root --oversubscribe --bind-to none "$vmsim" run "$job" --out "$dir" --no-render -q >/dev/null
    fi
    python3 - "$dir/report.json" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
t = r["timings_s"]
print(f"   report: removal {t['removal']:.1f} s, total {t['total']:.1f} s, sweeps {r['removal']['sweeps']}, rays {r['removal']['rays']}")
for k in r.get("tiles", {}).get("per_rank", []):
    print(f"   rank {k['rank']}: rows {k['rows']:.0f}, rays {k['rays']:.0f}, sweeps {k['sweeps']:.0f}, removal {k['removal_s']:.1f} s wall {k.get('removal_cpu_s',0):.1f} s cpu, process cpu {k.get('cpu_s',0):.1f} s, peak rss {k['peak_rss_bytes']/1e6:.0f} MB")
EOF
  done
  cmp "$out/r${r}_np1/surface.npy" "$out/r${r}_np2/surface.npy" && echo "   surface.npy identical (1 and 2 ranks)"
done
