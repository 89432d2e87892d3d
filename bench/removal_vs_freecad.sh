#!/bin/sh
# vmsim's z-map kernel against FreeCAD 0.20's path simulator on the peer raster (bench/README.md, "Material removal
# (issue 4)"), interleaved: per round and spacing, FreeCAD split then vmsim on one thread, each its own process, the
# load average printed before each run. Figures: CPU time of each tool's cut loop (FreeCAD: process_time() round its
# ApplyCommand loop; vmsim: Google Benchmark's CPU time of cut()), and vmsim's heights against the exact envelope
# ref.xyz. The FreeCAD copy stops after its loop (its mesh and the pure-Python height sampling are not timed and take
# up to a minute); its heights' error is in bench/README.md.
#
# usage: VMSIM_SHARED_DIR=../shared bench/removal_vs_freecad.sh BUILD_DIR [ROUNDS] [SPACINGS as 1/n mm: "16 32"]
#          [KERNELS: "0" cut(), "0 1" also cut_reference(), the kernel before issue 21, in the same round]
# BENCH_BEFORE=path/to/another/removal_bench adds that build's cut() to each round (a before/after of a change).
# needs freecadcmd (apt-get install --no-install-recommends freecad) and BUILD_DIR/bench/removal_bench.
set -eu
build=$(cd "$1" && pwd)
rounds=${2:-2}
spacings=${3:-"16 32"}
kernels=${4:-0}
peers=${VMSIM_SHARED_DIR:?set VMSIM_SHARED_DIR to the shared folder (it holds peers/)}/peers
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
cd "$scratch"
cp "$peers/peer_envelope_grid.py" .
# The peer script up to its loop, timed by CPU.
sed -n '1,/^t_sim = /p' "$peers/peer_freecad_sim.py" | sed 's/time\.time()/time.process_time()/g' > fc_loop.py
echo 'print("RESULT_LOOP res=%g split=%g applied=%d loop_cpu_s=%.3f" % (res, split, ncut, t_sim))' >> fc_loop.py
python3 peer_envelope_grid.py 1.0 ref.xyz > /dev/null
err() {  # height error of an "x y z" file against ref.xyz, node by node (the command in bench/README.md)
  awk 'NR==FNR{r[$1+0" "$2+0]=$3;next} ($1+0" "$2+0) in r{d=$3-r[$1+0" "$2+0]; n++; s+=d*d; if(n==1||d<lo)lo=d;
    if(n==1||d>hi)hi=d} END{printf "n=%d min=%+.6f max=%+.6f rms=%.6f mm\n",n,lo,hi,sqrt(s/n)}' ref.xyz "$1"
}
for r in $(seq 1 "$rounds"); do
  for n in $spacings; do
    res=$(python3 -c "print(1/$n)")
    echo "round $r n=$n freecad load $(cut -d' ' -f1-3 /proc/loadavg)"
    PEER_RES=$res PEER_TOOL=ball PEER_SPLIT=0.25 PEER_OUT=fc freecadcmd fc_loop.py 2>&1 | grep -a -o 'RESULT_LOOP.*'
    for k in ${BENCH_BEFORE:+before} $kernels; do
      exe=$build/bench/removal_bench kk=$k
      if [ "$k" = before ]; then exe=$BENCH_BEFORE kk=0; fi
      echo "round $r n=$n vmsim kernel $k load $(cut -d' ' -f1-3 /proc/loadavg)"
      VMSIM_REMOVAL_HEIGHTS="$scratch/vmh" /usr/bin/time -f "vmsim process user %U s sys %S s maxrss %M KB" \
        "$exe" --benchmark_filter="BM_ZmapBallRaster/n:$n/threads:1/kernel:$kk/" \
        --benchmark_format=json --benchmark_out=vm.json > /dev/null 2> time.txt
      python3 -c "import json; b=json.load(open('vm.json'))['benchmarks'][0]; print('vmsim kernel $k cut_cpu_s=%.3f' % (b['cpu_time']/1e3), 'ray_tests=%d' % b['ray_tests'], ' '.join('%s=%.2f' % (c, b[c]) for c in ('tile_skip_%', 'row_skip_%', 'bound_skip_%', 'exact_nil_%', 'cut_%') if c in b))"
      cat time.txt
      echo "vmsim heights vs ref.xyz: $(err vmh_${n}_t1.xyz)"
    done
  done
done
