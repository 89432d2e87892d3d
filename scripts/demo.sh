#!/usr/bin/env bash
# make demo: the plane-cylinder part of seed 004 (section 4) through the stages of the chain that exist so far.
# Usage: scripts/demo.sh PATH/TO/vmsim
set -euo pipefail
vmsim=${1:?usage: scripts/demo.sh PATH/TO/vmsim}
here=$(cd "$(dirname "$0")/.." && pwd)
part="$here/parts/plane_cylinder"

echo "== vmsim demo: plane-cylinder part (seed 004 section 4), ball-end D10, passes in XZ planes 0.25 mm apart"
echo "   floor, concave R10 fillet, 30 deg slope; Mikron UCP 710 limits (seed 000 Table I); Te 1 ms, tolerance 20 um"
echo
for job in reference fast; do
  echo "-- job_$job.toml"
  "$vmsim" interp "$part/job_$job.toml" --summary-only
  echo
done
echo "Setpoints of a job: $vmsim interp $part/job_fast.toml --out DIR   (writes DIR/setpoints.csv)"
