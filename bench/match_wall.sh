#!/usr/bin/env bash
# Wall time of the whole `funcorr match X Y -o DIR --no-render` process (default pipeline) for one
# or more funcorr binaries, on the first N pairs of a data set, with the eigenbases cached (warm)
# and without the cache (--no-cache: spectra included). Each (binary, pair, mode) runs REPS times;
# prints the median per pair and the mean of the medians.
#
#   bench/match_wall.sh DATASET N REPS BINARY [BINARY...]
#   e.g. bench/match_wall.sh ../shared/data/faust_r 5 3 target/release/funcorr /tmp/old/funcorr
set -euo pipefail
ds=$1; n=$2; reps=$3; shift 3
out=$(mktemp -d)
cache=$(mktemp -d)
trap 'rm -rf "$out" "$cache"' EXIT
pairs=$(grep -v '^#' "$ds/pairs.txt" | head -n "$n")
shape() { for e in off ply obj; do if [ -f "$ds/$1.$e" ]; then echo "$ds/$1.$e"; return; fi; done; }
for bin in "$@"; do
  for mode in warm cold; do
    extra=(); [ "$mode" = cold ] && extra=(--no-cache)
    meds=()
    while read -r x y; do
      [ -z "$x" ] && continue
      px=$(shape "$x"); py=$(shape "$y")
      # warm the cache once (not timed)
      FUNCORR_CACHE_DIR=$cache "$bin" match "$px" "$py" -o "$out/m" --no-render -q
      ts=()
      for _ in $(seq "$reps"); do
        s=$(date +%s.%N)
        FUNCORR_CACHE_DIR=$cache "$bin" match "$px" "$py" -o "$out/m" --no-render -q "${extra[@]}"
        e=$(date +%s.%N)
        ts+=("$(echo "$e - $s" | bc -l)")
      done
      med=$(printf '%s\n' "${ts[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
      meds+=("$med")
      printf '%s %s %s → %s: %.2f s\n' "$bin" "$mode" "$x" "$y" "$med"
    done <<< "$pairs"
    printf '%s %s: mean of medians %.2f s over %d pairs\n' "$bin" "$mode" \
      "$(printf '%s\n' "${meds[@]}" | awk '{s+=$1} END {print s/NR}')" "${#meds[@]}"
  done
done
