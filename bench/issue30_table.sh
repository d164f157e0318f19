#!/usr/bin/env bash
# Issue 30's "Done when": one table of every size, measured by this one script in one session,
# one process at a time (run it on an otherwise idle machine; it prints the load average).
#
#   1. pyfm5k    5k pairs: `funcorr match` defaults vs pyFM's recipe on the first PAIRS_5K faust_r
#                pairs (bench/pyfm_side_by_side.sh: wall, peak memory, errors, the ratio per pair).
#   2. large     cat0 → cat10 (28k) and david0 → david1 (52k): the same two processes under GNU
#                time, errors by `funcorr eval` (exact geodesics) on 500 seeded vertices, truth
#                the identity (tosca_hires shapes share their vertex order).
#   3. spectrum  `funcorr spectrum` vs scipy `eigsh` (bench/spectrum_vs_scipy.sh) at 5k, 28k,
#                52k; and `funcorr spectrum -k 100` on the ≈ 10⁶-vertex shape.
#   4. million   the ≈ 10⁶-vertex pair (two midpoint subdivisions of david0 / david1, made by
#                examples/subdivide.rs unless BIG holds them): whole `funcorr match` under GNU
#                time, error on 500 seeded coarse vertices with exact geodesics on the
#                subdivided david1 (the same surface as the coarse one) beside the 52k pair's on
#                the same vertices, and with the images snapped to the coarse vertices
#                (bench/subdivided_error.py).
#   5. completion `--method completion` on faust_r pairs 5–12, scarce and rich data
#                (bench/completion_speed.sh).
#   6. batch     all 97 faust_r pairs: `funcorr bench`, funcorr.batch local and Ray
#                (bench/batch_throughput.sh; PY= an interpreter with this commit's funcorr and
#                ray, else this commit's package installed into bench/.venv-batch first).
#
#     bash bench/issue30_table.sh                       # everything (about an hour on 2 cores)
#     STEPS="large million" BIG=/data/big bash bench/issue30_table.sh
#
# Knobs: SHARED (../shared), OUT (bench/out/issue30), FUNCORR_BIN (target/release/funcorr, built
# unless SKIP_BUILD=1), STEPS, PAIRS_5K (10), BIG (where the subdivided pair lives or is made;
# default $OUT/big), LARGE_REPEATS (3: timed runs per shape and k of the large shapes' eigsh rows,
# the fastest reported; 1 halves the step's time but leaves single runs' noise in the ratios).
# Results: $OUT/<step>/..., a summary in $OUT/summary.md.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

SHARED=${SHARED:-../shared}
D=$SHARED/data
OUT=${OUT:-bench/out/issue30}
FUNCORR_BIN=${FUNCORR_BIN:-target/release/funcorr}
STEPS=${STEPS:-"pyfm5k large spectrum million completion batch"}
PAIRS_5K=${PAIRS_5K:-10}
BIG=${BIG:-$OUT/big}
mkdir -p "$OUT"
SUMMARY=$OUT/summary.md

log() { echo "[issue30 $(date -u +%H:%M:%S)] $*" >&2; }
note() { echo "$*" >>"$SUMMARY"; }
command -v /usr/bin/time >/dev/null || { echo "error: GNU time (/usr/bin/time) is needed" >&2; exit 1; }
if [[ ${SKIP_BUILD:-0} != 1 ]]; then
    cargo build --release >&2
fi
[[ -x $FUNCORR_BIN ]] || { echo "error: $FUNCORR_BIN not found" >&2; exit 1; }

{
    echo "# Issue 30 table, $(date -u +%Y-%m-%dT%H:%MZ)"
    echo
    echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo '?'), $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GB", $2 / 1048576}' /proc/meminfo), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
    echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
    echo
} >"$SUMMARY"

# Seconds, CPU seconds and peak RSS (MB) of one process: `timed FILE cmd...` writes
# "wall user+sys maxrss_kb" to FILE.
timed() {
    local file=$1
    shift
    /usr/bin/time -f "%e %U %S %M" -o "$file" "$@"
}
fmt_time() { awk '{ printf "%.2f s wall, %.1f s CPU, %.0f MB", $1, $2 + $3, $4 / 1024 }' "$1"; }

# 500 seeded vertex ids (1-based) of a shape with n vertices, as a .vts file.
sample_ids() {
    python3 -c "
import random, sys
n = int(sys.argv[1])
ids = sorted(random.Random(11).sample(range(1, n + 1), 500))
open(sys.argv[2], 'w').write('\n'.join(map(str, ids)) + '\n')" "$1" "$2"
}
n_vertices() { awk 'NR == 2 { print $1; exit }' "$1"; }
mean_error() {
    "$FUNCORR_BIN" eval --source "$1" --target "$2" --map "$3" --gt-source "$4" --gt-target "$4" |
        awk '/mean error/ { print $NF }'
}

for step in $STEPS; do
    case $step in
    pyfm5k)
        log "5k pairs against pyFM ($PAIRS_5K pairs)"
        DATASETS=faust_r PAIRS_N=$PAIRS_5K SKIP_BUILD=1 FUNCORR_BIN=$FUNCORR_BIN OUT=$OUT/pyfm5k SHARED=$SHARED \
            bash bench/pyfm_side_by_side.sh >"$OUT/pyfm5k.log" 2>&1
        note "## 5k: funcorr vs pyFM (first $PAIRS_5K faust_r pairs)"
        note
        cat "$OUT/pyfm5k/summary.md" >>"$SUMMARY"
        note
        ;;
    large)
        [[ -x bench/.venv/bin/python ]] || { echo "error: bench/.venv (made by the pyfm5k step) is needed" >&2; exit 1; }
        note "## Large pairs: funcorr vs pyFM's recipe (whole processes, no cache)"
        note
        note "| pair | n, m | funcorr | error ×100 | pyFM recipe | error ×100 | wall ratio |"
        note "| --- | --- | --- | ---: | --- | ---: | ---: |"
        for pair in "cat0 cat10" "david0 david1"; do
            read -r xn yn <<<"$pair"
            x=$D/tosca_hires/$xn.off
            y=$D/tosca_hires/$yn.off
            dir=$OUT/large/${xn}_$yn
            mkdir -p "$dir"
            log "large pair $xn → $yn: funcorr"
            timed "$dir/funcorr.time" "$FUNCORR_BIN" match "$x" "$y" --no-cache --no-render -q -o "$dir/funcorr"
            log "large pair $xn → $yn: pyFM"
            timed "$dir/pyfm.time" bench/.venv/bin/python bench/pyfm_pipeline.py run --x "$x" --y "$y" \
                --out "$dir/pyfm" --variant example >"$dir/pyfm.log" 2>&1
            sample_ids "$(n_vertices "$x")" "$dir/gt500.vts"
            ef=$(mean_error "$x" "$y" "$dir/funcorr/map.txt" "$dir/gt500.vts")
            ep=$(mean_error "$x" "$y" "$dir/pyfm/example.zoomout.map.txt" "$dir/gt500.vts")
            ratio=$(awk -v a="$(cut -d' ' -f1 "$dir/funcorr.time")" -v b="$(cut -d' ' -f1 "$dir/pyfm.time")" 'BEGIN { printf "%.3f", a / b }')
            note "| $xn → $yn | $(n_vertices "$x"), $(n_vertices "$y") | $(fmt_time "$dir/funcorr.time") | $ef | $(fmt_time "$dir/pyfm.time") | $ep | $ratio |"
        done
        note
        ;;
    spectrum)
        log "spectrum vs scipy eigsh"
        SKIP_BUILD=1 REPEATS=3 KS="50 100 200 350" SHAPES="$D/faust_r/tr_reg_000.off" FUNCORR_BIN=$FUNCORR_BIN \
            OUT=$OUT/spectrum5k SHARED=$SHARED bash bench/spectrum_vs_scipy.sh >"$OUT/spectrum5k.md" 2>"$OUT/spectrum5k.log"
        SKIP_BUILD=1 REPEATS=${LARGE_REPEATS:-3} KS="50 100 200 350" SHAPES="$D/tosca_hires/cat0.off $D/tosca_hires/david0.off" \
            FUNCORR_BIN=$FUNCORR_BIN OUT=$OUT/spectrum_large SHARED=$SHARED \
            bash bench/spectrum_vs_scipy.sh >"$OUT/spectrum_large.md" 2>"$OUT/spectrum_large.log"
        note "## Eigenbasis: funcorr spectrum vs scipy eigsh"
        note
        cat "$OUT/spectrum5k.md" "$OUT/spectrum_large.md" >>"$SUMMARY"
        note
        ;;
    million)
        mkdir -p "$BIG"
        for s in david0 david1; do
            if [[ ! -f $BIG/${s}_x16.off ]]; then
                log "subdividing $s twice"
                cargo run --release --example subdivide -- "$D/tosca_hires/$s.off" 2 "$BIG/${s}_x16.off" >&2
            fi
        done
        dir=$OUT/million
        mkdir -p "$dir"
        log "10⁶: spectrum -k 100"
        timed "$dir/spectrum.time" "$FUNCORR_BIN" spectrum "$BIG/david0_x16.off" -k 100 --no-cache -o "$dir/spectrum.npz" 2>"$dir/spectrum.log"
        log "10⁶: match"
        timed "$dir/match.time" "$FUNCORR_BIN" match "$BIG/david0_x16.off" "$BIG/david1_x16.off" --no-cache --no-render \
            -o "$dir/match" 2>"$dir/match.log" &
        tpid=$!
        # Resident memory over time (seconds since start, MB), to place the peak among the stages.
        t0=$(date +%s.%N)
        while kill -0 "$tpid" 2>/dev/null; do
            rss=$(pgrep -f "match $BIG/david0_x16.off" | xargs -r ps -o rss= -p | sort -n | tail -1)
            [[ -n $rss ]] && awk -v t="$(date +%s.%N)" -v t0="$t0" -v r="$rss" 'BEGIN { printf "%.0f %.0f\n", t - t0, r / 1024 }'
            sleep 1
        done >"$dir/rss.txt"
        wait "$tpid"
        coarse=$OUT/large/david0_david1/funcorr/map.txt
        [[ -f $coarse ]] || { echo "error: the large step's david map ($coarse) is needed" >&2; exit 1; }
        bench/.venv/bin/python bench/subdivided_error.py "$BIG/david1_x16.off" "$D/tosca_hires/david1.off" \
            "$dir/match/map.txt" "$coarse" "$dir/err" >"$dir/proxy.txt"
        # The fine map on its own surface (exact geodesics on the subdivided mesh, which is the
        # 52k surface: the same distances) and, more strictly, snapped to the 52k vertices.
        e_own=$(mean_error "$BIG/david0_x16.off" "$BIG/david1_x16.off" "$dir/match/map.txt" "$dir/err/gt500.vts")
        e_fine=$(mean_error "$D/tosca_hires/david0.off" "$D/tosca_hires/david1.off" "$dir/err/snapped_map.txt" "$dir/err/gt500.vts")
        e_coarse=$(mean_error "$D/tosca_hires/david0.off" "$D/tosca_hires/david1.off" "$coarse" "$dir/err/gt500.vts")
        note "## The ≈ 10⁶-vertex pair ($(n_vertices "$BIG/david0_x16.off") and $(n_vertices "$BIG/david1_x16.off") vertices)"
        note
        note "- \`funcorr spectrum david0_x16 -k 100 --no-cache\`: $(fmt_time "$dir/spectrum.time")"
        ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", a / b }'; }
        note "- \`funcorr match\` (no cache): $(fmt_time "$dir/match.time"); error ×100 on its own (subdivided) surface $e_own, the 52k pair on the same 500 vertices $e_coarse: ratio $(ratio "$e_own" "$e_coarse"); the fine map's images snapped to the nearest 52k vertex: $e_fine, ratio $(ratio "$e_fine" "$e_coarse") (snapping adds the 52k mesh's rounding to a map that has none)"
        note "- stages: $(grep -o 'funcorr: .*' "$dir/match.log" | tail -1)"
        note "- resident memory over time: $dir/rss.txt (seconds, MB); largest $(sort -k2 -n "$dir/rss.txt" | tail -1 | awk '{ print $2 " MB at " $1 " s" }')"
        note
        ;;
    completion)
        log "completion method, faust_r pairs 5-12"
        bash bench/completion_speed.sh "$D/faust_r" 5 8 "$FUNCORR_BIN" "1000" >"$OUT/completion.md" 2>"$OUT/completion.log"
        note "## --method completion (faust_r pairs 5–12, whole process, no cache)"
        note
        cat "$OUT/completion.md" >>"$SUMMARY"
        note
        ;;
    batch)
        log "batch throughput, 97 faust_r pairs"
        # PY: an interpreter with this commit's funcorr and ray; without it batch_throughput.sh
        # installs this commit's package into bench/.venv-batch first (untimed), so that the
        # local and Ray rows never run an older build.
        PY=${PY:-} OUT=$OUT/batch SHARED=$SHARED bash bench/batch_throughput.sh >"$OUT/batch.md" 2>"$OUT/batch.log"
        note "## Batch throughput (97 faust_r pairs)"
        note
        cat "$OUT/batch.md" >>"$SUMMARY"
        note
        ;;
    *)
        echo "error: unknown step '$step' (pyfm5k large spectrum million completion batch)" >&2
        exit 1
        ;;
    esac
done
note "load average at end: $(cut -d' ' -f1-3 /proc/loadavg)"
log "done: $SUMMARY"
