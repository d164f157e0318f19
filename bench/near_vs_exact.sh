#!/usr/bin/env bash
# Exact against restricted (--near-above 0) searches of the default pipeline on faust_lps
# 8k → 15k pairs (EXPERIMENTS.md, "Restricted searches below the large-pair threshold").
# Usage: bench/near_vs_exact.sh [FUNCORR] [PAIRS]   (default target/release/funcorr, 12 pairs)
# Error: `funcorr eval` on 500 seeded random template vertices (faust_lps: the first 6,890
# vertices of every shape are the template's, so the truth is the identity on them).
set -euo pipefail
B=${1:-target/release/funcorr}
N=${2:-12}
D=${DATA:-../shared/data/faust_lps}
OUT=$(mktemp -d)
python3 -c "
import random
ids = sorted(random.Random(11).sample(range(1, 6891), 500))
open('$OUT/gt.vts', 'w').write('\n'.join(map(str, ids)) + '\n')"
head -"$N" "$D/pairs.txt" | while read -r x y; do
  for mode in exact near; do
    extra=()
    [ "$mode" = near ] && extra=(--near-above 0)
    o="$OUT/$x-$y-$mode"
    "$B" match "$D/8000/$x.off" "$D/15000/$y.off" --no-render -q -o "$o" "${extra[@]}" > /dev/null
    e=$("$B" eval --source "$D/8000/$x.off" --target "$D/15000/$y.off" --map "$o/map.txt" \
      --gt-source "$OUT/gt.vts" --gt-target "$OUT/gt.vts" | awk '/mean error/ {print $NF}')
    echo "$x $y $mode $e"
  done
done
