#!/usr/bin/env bash
# make demo: the plane-cylinder part (seed 004 section 4) through the stages that exist so far.
set -euo pipefail
echo "demo: not yet available" >&2
