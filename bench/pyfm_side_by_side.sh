#!/usr/bin/env bash
# Side by side with pyFM on every pair (issue 11): `funcorr match X Y` with no options against
# pyFM's documented recipe (PyPI `pyfmaps`: README quickstart / gallery "maps without
# correspondence", fit weights 1 / 0.1 / 1 / 1, then ICP and ZoomOut 30 -> 110), on every pair of
# faust_r, tosca_r and tosca_nonisometric_r. Every map is scored by the same evaluator
# (`funcorr eval`, exact geodesics), direct (no flip forgiven) and symmetric (left-right flip
# forgiven), and each tool's seconds per pair are measured in this script, one process at a time.
#
# Run from the repository root:
#     bash bench/pyfm_side_by_side.sh                                  # all three data sets, every pair
#     DATASETS=faust_r PAIRS_N=3 bash bench/pyfm_side_by_side.sh       # quick check
#
# Environment knobs:
#   SHARED=../shared        where shared/ lives (data sets in $SHARED/data/<name>)
#   DATASETS="faust_r tosca_r tosca_nonisometric_r"
#   PAIRS_N=all             first N pairs of each data set's pairs.txt
#   OUT=bench/out/side_by_side   per-pair folders <OUT>/<dataset>/<X>_<Y>/, summary.md, results.json
#   FUNCORR_BIN=target/release/funcorr;  SKIP_BUILD=1: don't run `cargo build --release`
#   FUNCORR_ARGS=""         extra options of `funcorr match` (empty: the defaults, the point of the benchmark)
#   RESUME=1                skip pairs whose maps and timings already exist (after an interruption)
#   EVAL_JOBS=2             parallel `funcorr eval` jobs (untimed, after all timed runs)
# Needs python3 >= 3.11 (with venv); creates/reuses bench/.venv with bench/requirements-pyfm.txt.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."

SHARED=${SHARED:-../shared}
DATASETS=${DATASETS:-"faust_r tosca_r tosca_nonisometric_r"}
PAIRS_N=${PAIRS_N:-all}
OUT=${OUT:-bench/out/side_by_side}
FUNCORR_BIN=${FUNCORR_BIN:-target/release/funcorr}
SKIP_BUILD=${SKIP_BUILD:-0}
FUNCORR_ARGS=${FUNCORR_ARGS:-}
RESUME=${RESUME:-0}
EVAL_JOBS=${EVAL_JOBS:-2}
VENV=bench/.venv
PY=$VENV/bin/python
REQ=bench/requirements-pyfm.txt

log() { echo "[bench] $*" >&2; }
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.6f", b - a }'; }

if ! command -v python3 >/dev/null || ! python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    echo "error: python3 >= 3.11 (with the venv module) is required for the pinned numpy/scipy" >&2
    exit 1
fi
if [[ ! -x $PY ]] || ! cat bench/requirements.txt "$REQ" | cmp -s - "$VENV/.requirements-pyfm.installed"; then
    log "setting up $VENV from $REQ"
    [[ -x $PY ]] || python3 -m venv "$VENV"
    "$VENV/bin/pip" install --disable-pip-version-check -q -r "$REQ" >&2
    cat bench/requirements.txt "$REQ" >"$VENV/.requirements-pyfm.installed"
    cp bench/requirements.txt "$VENV/.requirements.installed"
fi
if [[ $SKIP_BUILD != 1 ]]; then
    log "cargo build --release"
    cargo build --release >&2
fi
[[ -x $FUNCORR_BIN ]] || { echo "error: $FUNCORR_BIN not found or not executable" >&2; exit 1; }

mkdir -p "$OUT"
"$PY" bench/pyfm_pipeline.py env --out "$OUT/env.json" --funcorr-bin "$FUNCORR_BIN"
load1=$(cut -d' ' -f1 /proc/loadavg)
if awk -v l="$load1" 'BEGIN { exit !(l > 0.5) }'; then
    log "WARNING: 1-minute load average is $load1: other processes are using the CPUs, timings will be noisy"
fi

# peak FILE CMD...: runs CMD, writing its peak resident memory (KB) to FILE with GNU time when
# it is there.
peak() {
    local file=$1
    shift
    if [[ -x /usr/bin/time ]]; then
        /usr/bin/time -f %M -o "$file" "$@"
    else
        "$@"
    fi
}

EVAL_LIST=$OUT/eval_jobs.txt
: >"$EVAL_LIST"
T_START=$(now)
for ds in $DATASETS; do
    data=$SHARED/data/$ds
    [[ -f $data/pairs.txt ]] || { echo "error: $data/pairs.txt not found (set SHARED=...)" >&2; exit 1; }
    count=0
    while IFS=$'\t ' read -r xn yn _; do
        [[ -n $xn && -n $yn ]] || continue
        [[ $PAIRS_N == all ]] || ((count < PAIRS_N)) || break
        count=$((count + 1))
        x=$data/$xn.off
        y=$data/$yn.off
        dir=$OUT/$ds/${xn}_$yn
        mkdir -p "$dir"
        if [[ $RESUME == 1 && -f $dir/funcorr.wall && -f $dir/pyfm.wall ]]; then
            log "$ds $xn -> $yn: done before (RESUME=1)"
        else
            rm -rf "${dir:?}"/*
            cut -d' ' -f1-3 /proc/loadavg >"$dir/loadavg"
            t0=$(now)
            # shellcheck disable=SC2086
            if peak "$dir/funcorr.maxrss" "$FUNCORR_BIN" match "$x" "$y" $FUNCORR_ARGS --no-render --no-cache -o "$dir/funcorr" \
                    >"$dir/funcorr.stdout" 2>"$dir/funcorr.stderr"; then
                elapsed "$t0" "$(now)" >"$dir/funcorr.wall"
            else
                log "$ds $xn -> $yn: funcorr failed, see $dir/funcorr.stderr"
            fi
            t0=$(now)
            if peak "$dir/pyfm.maxrss" "$PY" bench/pyfm_pipeline.py run --x "$x" --y "$y" --out "$dir/pyfm" --variant example \
                    2>"$dir/pyfm.stderr"; then
                elapsed "$t0" "$(now)" >"$dir/pyfm.wall"
            else
                log "$ds $xn -> $yn: pyFM failed, see $dir/pyfm.stderr"
            fi
            cut -d' ' -f1-3 /proc/loadavg >>"$dir/loadavg"
            log "$ds $xn -> $yn: funcorr $(cat "$dir/funcorr.wall" 2>/dev/null || echo -) s, pyFM $(cat "$dir/pyfm.wall" 2>/dev/null || echo -) s"
        fi
        for m in "funcorr $dir/funcorr/map.txt" "pyfm-fmap $dir/pyfm/example.fmap.map.txt" \
                 "pyfm-icp $dir/pyfm/example.icp.map.txt" "pyfm-zoomout $dir/pyfm/example.zoomout.map.txt"; do
            read -r tag map <<<"$m"
            [[ -f $map ]] && echo "$data $xn $yn $dir $tag $map" >>"$EVAL_LIST"
        done
    done <"$data/pairs.txt"
done
log "timed runs done in $(elapsed "$T_START" "$(now)") s; evaluating $(wc -l <"$EVAL_LIST") maps (direct and symmetric)"

eval_one() {  # data xn yn dir tag map
    local data=$1 xn=$2 yn=$3 dir=$4 tag=$5 map=$6 kind
    for kind in sym direct; do
        local sym=()
        [[ $kind == sym ]] && sym=(--gt-target-sym "$data/corres/$yn.sym.vts")
        if ! "$FUNCORR_BIN" eval --source "$data/$xn.off" --target "$data/$yn.off" --map "$map" \
                --gt-source "$data/corres/$xn.vts" --gt-target "$data/corres/$yn.vts" "${sym[@]}" \
                --geodesics exact --json >"$dir/eval.$tag.$kind.json" 2>"$dir/eval.$tag.$kind.stderr"; then
            echo "[bench] eval failed: $dir/eval.$tag.$kind.stderr" >&2
            rm -f "$dir/eval.$tag.$kind.json"
        fi
    done
}
export -f eval_one
export FUNCORR_BIN
xargs -P "$EVAL_JOBS" -L 1 bash -c 'eval_one "$@"' _ <"$EVAL_LIST"

"$PY" bench/side_by_side_summary.py --out "$OUT" --env "$OUT/env.json" \
    --command "$(printf 'DATASETS="%s" PAIRS_N=%s FUNCORR_ARGS="%s" bash bench/pyfm_side_by_side.sh' "$DATASETS" "$PAIRS_N" "$FUNCORR_ARGS")" \
    $DATASETS
log "total $(elapsed "$T_START" "$(now)") s; summary: $OUT/summary.md, per pair: $OUT/per_pair.md, raw: $OUT/results.json"
