#!/usr/bin/env bash
# make demo: the plane-cylinder part of the feed-drive simulation paper (section 4) through the whole chain: interpolator, servo drives,
# material removal, and the mark the fast pass leaves at the fillet.
# Usage: scripts/demo.sh PATH/TO/vmsim
set -euo pipefail
# The fast pass runs first: its mark table is the result a new user waits for; the whole part at 0.1 m/min follows.
vmsim=${1:?usage: scripts/demo.sh PATH/TO/vmsim}
here=$(cd "$(dirname "$0")/.." && pwd)
part="$here/parts/plane_cylinder"
out="$here/build/demo"

echo "== vmsim demo: plane-cylinder part (the feed-drive simulation paper section 4): floor, concave R10 fillet, 30 deg slope; ball-end D10,"
echo "   passes in XZ planes 0.25 mm apart on a stock with 0.05 mm allowance; Mikron UCP 710 (Duong et al. Table I)."
echo
echo "-- 10 m/min: the middle pass; its mark against the same pass at 0.1 m/min (the feed-drive simulation paper: about 0.02 mm)"
"$vmsim" run "$part/job_fast.toml" --out "$out/fast"
echo
echo "-- 0.1 m/min: every pass; its marks against the program cut exactly (the feed-drive simulation paper: negligible)"
"$vmsim" run "$part/job_reference.toml" --out "$out/reference"
echo
echo "Results (report.json, surface/deviation grids, part.stl, part.vtp, signals.csv): $out/reference and $out/fast"
echo
echo "Pictures (PNG, drawn off-screen with no display; redraw with: $vmsim render DIR [--size WxH]):"
for f in part part_mark deviation deviation_mark deviation_3d contour_error feed; do
  if [ -f "$out/fast/images/$f.png" ]; then echo "  $out/fast/images/$f.png"; fi
done
echo "  ... and the axis, position and current charts: $out/fast/images/ and $out/reference/images/"
echo "Setpoints and drive signals of a job: $vmsim motion $part/job_fast.toml --out DIR"
echo
echo "The report of the fast pass (the mark, its pictures, the charts, every figure) is one page:"
echo "  $out/fast/report.html"
echo "Open it with:  xdg-open $out/fast/report.html"
