#!/usr/bin/env bash
# Wall time of the whole `funcorr match --method completion` process (cold: spectra included,
# --no-cache) with the paper's scarce data (the pair's provided .seg.sym segments, k' = 350,
# k = 250) and rich data (`--data rich:...`, k' = 50, k = 30), 150 L-BFGS iterations (as Figure 7
# in EXPERIMENTS.md), for the L1 term on every vertex and on farthest-point samples, side by side
# on the same pairs; the geodesic error of each map (symmetric flips allowed) from `funcorr eval`.
#
#   bench/completion_speed.sh DATASET FIRST N BINARY "SAMPLES..." ["OPTIONS;OPTIONS;..."]
#   e.g. bench/completion_speed.sh ../shared/data/faust_r 5 3 target/release/funcorr "0 1000"
#   (SAMPLES 0 = every vertex; pairs FIRST..FIRST+N-1 of pairs.txt, 1-based line numbers;
#   the optional last argument lists extra `match` option sets separated by ';', each run for
#   every SAMPLES value, e.g. ";--l1-f32;--multiscale 2" — an empty set is `funcorr match`'s
#   defaults: since commit 7f55c16 f32 products and two scales, so compare with
#   "--l1-precision f64 --multiscale 1" for the paper's arithmetic)
set -euo pipefail
ds=$1; first=$2; n=$3; bin=$4; samples=$5; variants=${6:-}
IFS=';' read -r -a option_sets <<< "$variants"
[ ${#option_sets[@]} -eq 0 ] && option_sets=("")
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
pairs=$(grep -v '^#' "$ds/pairs.txt" | sed -n "${first},$((first + n - 1))p")
printf '| setting | L1 samples | options | pair | seconds | completion s | iterations | mean error ×100 |\n|---|---:|---|---|---:|---:|---:|---:|\n'
while read -r x y; do
  [ -z "$x" ] && continue
  seg="$ds/segmentation/${x}_${y}"
  for setting in scarce rich; do
    if [ "$setting" = scarce ]; then
      data=(--data "segments:$seg.$x.seg.sym,$seg.$y.seg.sym" --kprime 350 -k 250)
    else
      data=(--data "rich:$seg.$x.seg.sym,$seg.$y.seg.sym" --kprime 50 -k 30)
    fi
    for s in $samples; do
     for opts in "${option_sets[@]}"; do
      read -r -a extra <<< "$opts"
      o="$out/$setting-$s"
      rm -rf "$o"
      t0=$(date +%s.%N)
      "$bin" match "$ds/$x.off" "$ds/$y.off" --method completion "${data[@]}" --max-iterations 150 \
        --refine icp --l1-samples "$s" --no-cache --no-render -q ${extra[@]+"${extra[@]}"} -o "$o"
      t1=$(date +%s.%N)
      read -r comp its < <(python3 -c "
import json; r = json.load(open('$o/report.json'))
st = dict((s['stage'], s['seconds']) for s in r.get('stages', []))
print(round(st.get('completion', float('nan')), 2), r['solver']['iterations'])")
      err=$("$bin" eval --source "$ds/$x.off" --target "$ds/$y.off" --map "$o/map.txt" \
        --gt-source "$ds/corres/$x.vts" --gt-target "$ds/corres/$y.vts" --gt-target-sym "$ds/corres/$y.sym.vts" \
        | awk '/mean error/ {print $NF}')
      printf '| %s | %s | %s | %s → %s | %.2f | %s | %s | %s |\n' "$setting" "$s" "${opts:-default}" "$x" "$y" "$(echo "$t1 - $t0" | bc -l)" "$comp" "$its" "$err"
     done
    done
  done
done <<< "$pairs"
