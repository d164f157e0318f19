#!/usr/bin/env bash
# Stage-by-stage side-by-side benchmark (issue 6; the all-pairs comparison of the defaults is
# bench/pyfm_side_by_side.sh): funcorr's functional-map pipeline vs pyFM (PyPI `pyfmaps`) on
# the FAUST remeshed pairs, both maps scored by the same evaluator (`funcorr eval`, exact
# geodesics, with and without the symmetric flip). Prints Markdown tables (per pair + mean) on
# stdout, progress on stderr; writes bench/out/pyfm_table.md and bench/out/pyfm_results.json.
#
# Run from the repository root:
#     bash bench/pyfm_stages.sh
#     SKIP_BUILD=1 FUNCORR_BIN=/path/to/funcorr PAIRS_N=2 bash bench/pyfm_stages.sh
#
# Environment knobs:
#   SHARED=../shared          where shared/ lives (data in $SHARED/data/faust_r)
#   DATA=$SHARED/data/faust_r data set folder (X.off, corres/X.vts, corres/X.sym.vts, pairs.txt)
#   PAIRS_N=5                 first N pairs of $DATA/pairs.txt
#   PAIRS="a:b c:d"           explicit pairs instead (shape names, source:target)
#   OUT=bench/out             output folder (per-pair files in $OUT/pyfm/<X>_<Y>/)
#   FUNCORR_BIN=target/release/funcorr   binary to benchmark
#   SKIP_BUILD=1              don't run `cargo build --release`
#   K=30                      functional-map size (pyFM fit K, funcorr -k)
#   K_PROCESS=200             eigenpairs per shape (pyFM process k, funcorr --kprime)
#   N_DESCR=100 SUBSAMPLE_STEP=2 K_DESCR=128   pyFM WKS: 100 energies, every 2nd kept, 128 eigenpairs
#   FUNCORR_DATA=wks:50       funcorr's descriptors (default: as many WKS as pyFM fits with)
#   ICP_NIT=10                ICP iterations (both)
#   ZO_NIT=16 ZO_STEP=5       ZoomOut: pyFM nit/step; funcorr --zoomout-to K+ZO_NIT*ZO_STEP --zoomout-step ZO_STEP
#   PYFM_VARIANTS="example plain plain-std"   pyFM fit weights: example = w_descr 1, w_lap 0.1,
#                             w_dcomm 1, w_orient 1 (pyFM's gallery/README); plain = w_dcomm = w_orient = 0;
#                             plain-std = plain with the standard (λi−λj)² commutativity mask instead of
#                             pyFM's resolvent mask; or NAME=w_descr,w_lap,w_dcomm,w_orient[,std]
#   INTRINSIC=0               1: pyFM process(intrinsic=True) (robust_laplacian's intrinsic Delaunay)
#   CROSS=1                   also run funcorr on pyFM's descriptors (--data matrix:...); 0 to skip
#   EVAL_JOBS=2               parallel `funcorr eval` jobs (run after all timed work)
#   GEODESICS=exact           funcorr eval --geodesics (exact | heat | dijkstra)
# Needs python3 >= 3.11 (with venv); creates/reuses bench/.venv with bench/requirements-pyfm.txt.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."

SHARED=${SHARED:-../shared}
DATA=${DATA:-$SHARED/data/faust_r}
PAIRS_N=${PAIRS_N:-5}
PAIRS=${PAIRS:-}
OUT=${OUT:-bench/out}
FUNCORR_BIN=${FUNCORR_BIN:-target/release/funcorr}
SKIP_BUILD=${SKIP_BUILD:-0}
K=${K:-30}
K_PROCESS=${K_PROCESS:-200}
N_DESCR=${N_DESCR:-100}
SUBSAMPLE_STEP=${SUBSAMPLE_STEP:-2}
K_DESCR=${K_DESCR:-128}
FUNCORR_DATA=${FUNCORR_DATA:-wks:$(((N_DESCR + SUBSAMPLE_STEP - 1) / SUBSAMPLE_STEP))}
ICP_NIT=${ICP_NIT:-10}
ZO_NIT=${ZO_NIT:-16}
ZO_STEP=${ZO_STEP:-5}
ZO_TO=$((K + ZO_NIT * ZO_STEP))
PYFM_VARIANTS=${PYFM_VARIANTS:-"example plain plain-std"}
INTRINSIC=${INTRINSIC:-0}
CROSS=${CROSS:-1}
EVAL_JOBS=${EVAL_JOBS:-2}
GEODESICS=${GEODESICS:-exact}
VENV=bench/.venv
PY=$VENV/bin/python
REQ=bench/requirements-pyfm.txt

log() { echo "[bench] $*" >&2; }
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.6f", b - a }'; }

# --- prerequisites ------------------------------------------------------------------------------
if ! command -v python3 >/dev/null || ! python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    echo "error: python3 >= 3.11 (with the venv module) is required for the pinned numpy/scipy" >&2
    exit 1
fi
if ((K_PROCESS < ZO_TO)); then
    echo "error: ZoomOut needs K + ZO_NIT*ZO_STEP = $ZO_TO eigenpairs, K_PROCESS is $K_PROCESS" >&2
    exit 1
fi

# --- python virtualenv: bench/requirements.txt + pyFM (bench/requirements-pyfm.txt) --------------
if [[ ! -x $PY ]] || ! cat bench/requirements.txt "$REQ" | cmp -s - "$VENV/.requirements-pyfm.installed"; then
    log "setting up $VENV from $REQ"
    [[ -x $PY ]] || python3 -m venv "$VENV"
    "$VENV/bin/pip" install --disable-pip-version-check -q -r "$REQ" >&2
    cat bench/requirements.txt "$REQ" >"$VENV/.requirements-pyfm.installed"
    # the same pins as bench/spectrum_vs_scipy.sh installs: mark them as installed for it too
    cp bench/requirements.txt "$VENV/.requirements.installed"
fi

# --- build ------------------------------------------------------------------------------------------
if [[ $SKIP_BUILD != 1 ]]; then
    log "cargo build --release"
    cargo build --release >&2
fi
if [[ ! -x $FUNCORR_BIN ]]; then
    echo "error: $FUNCORR_BIN not found or not executable" >&2
    exit 1
fi

# --- pairs --------------------------------------------------------------------------------------
PAIR_LIST=()
if [[ -n $PAIRS ]]; then
    for p in $PAIRS; do PAIR_LIST+=("${p%%:*} ${p#*:}"); done
else
    if [[ ! -f $DATA/pairs.txt ]]; then
        echo "error: $DATA/pairs.txt not found (set SHARED=... or DATA=...)" >&2
        exit 1
    fi
    while IFS=$'\t ' read -r a b _; do
        [[ -n $a && -n $b ]] || continue
        PAIR_LIST+=("$a $b")
        ((${#PAIR_LIST[@]} < PAIRS_N)) || break
    done <"$DATA/pairs.txt"
fi
if [[ ${#PAIR_LIST[@]} == 0 ]]; then
    echo "error: no pairs" >&2
    exit 1
fi
for pair in "${PAIR_LIST[@]}"; do
    read -r x y <<<"$pair"
    for f in "$DATA/$x.off" "$DATA/$y.off" "$DATA/corres/$x.vts" "$DATA/corres/$y.vts" "$DATA/corres/$y.sym.vts"; do
        [[ -f $f ]] || { echo "error: $f not found" >&2; exit 1; }
    done
done

load1=$(cut -d' ' -f1 /proc/loadavg)
if awk -v l="$load1" 'BEGIN { exit !(l > 0.5) }'; then
    log "WARNING: 1-minute load average is $load1: other processes are using the CPUs, timings will be noisy"
fi

mkdir -p "$OUT/pyfm"
"$PY" bench/pyfm_pipeline.py env --out "$OUT/pyfm/env.json" --funcorr-bin "$FUNCORR_BIN"
log "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) CPUs;" \
    "$("$PY" -c 'from importlib.metadata import version as v; print(*(p + " " + v(p) for p in ("pyfmaps", "numpy", "scipy", "scikit-learn")))')"
log "${#PAIR_LIST[@]} pairs; K $K, $K_PROCESS eigenpairs, pyFM WKS $N_DESCR/$SUBSAMPLE_STEP, funcorr --data $FUNCORR_DATA," \
    "ICP $ICP_NIT it., ZoomOut $K -> $ZO_TO step $ZO_STEP; pyFM variants: $PYFM_VARIANTS"

VARIANT_ARGS=()
for v in $PYFM_VARIANTS; do VARIANT_ARGS+=(--variant "$v"); done

funcorr_match() {  # tag refine dir data x y
    local tag=$1 refine=$2 dir=$3 data=$4 x=$5 y=$6 t0 t1
    rm -rf "${dir:?}/${tag}_$refine"
    t0=$(now)
    if "$FUNCORR_BIN" match "$x" "$y" --method fmap --data "$data" -k "$K" --kprime "$K_PROCESS" \
            --refine "$refine" --icp-iterations "$ICP_NIT" --zoomout-to "$ZO_TO" --zoomout-step "$ZO_STEP" \
            --no-render --no-cache -o "$dir/${tag}_$refine" >"$dir/${tag}_$refine.stdout" 2>"$dir/${tag}_$refine.stderr"; then
        t1=$(now)
        elapsed "$t0" "$t1" >"$dir/${tag}_$refine.wall"
    else
        log "$(basename "$x" .off) -> $(basename "$y" .off): funcorr ($tag, --refine $refine) failed (exit $?), see $dir/${tag}_$refine.stderr"
    fi
}

# --- timed runs (sequential: nothing else runs meanwhile) -----------------------------------------
T_START=$(now)
EVAL_LIST=$OUT/pyfm/eval_jobs.txt
: >"$EVAL_LIST"
for pair in "${PAIR_LIST[@]}"; do
    read -r xn yn <<<"$pair"
    x=$DATA/$xn.off
    y=$DATA/$yn.off
    dir=$OUT/pyfm/${xn}_$yn
    mkdir -p "$dir"
    rm -f "$dir"/eval.*.json "$dir"/eval.*.stderr
    cut -d' ' -f1-3 /proc/loadavg >"$dir/loadavg"

    log "$xn -> $yn: funcorr ($FUNCORR_DATA; --refine none, icp, zoomout)"
    for refine in none icp zoomout; do funcorr_match funcorr "$refine" "$dir" "$FUNCORR_DATA" "$x" "$y"; done

    log "$xn -> $yn: pyFM"
    rm -rf "$dir/pyfm"
    if ! "$PY" bench/pyfm_pipeline.py run --x "$x" --y "$y" --out "$dir/pyfm" "${VARIANT_ARGS[@]}" \
            --k-process "$K_PROCESS" --intrinsic "$INTRINSIC" --n-descr "$N_DESCR" --k-descr "$K_DESCR" \
            --subsample-step "$SUBSAMPLE_STEP" --K "$K" --icp-nit "$ICP_NIT" --zo-nit "$ZO_NIT" \
            --zo-step "$ZO_STEP" 2>"$dir/pyfm.stderr"; then
        log "$xn -> $yn: pyFM failed, see $dir/pyfm.stderr"
    fi
    grep '^\[pyfm\]' "$dir/pyfm.stderr" >&2 || true

    if [[ $CROSS == 1 && -f $dir/pyfm/descr_x.npy ]]; then
        log "$xn -> $yn: funcorr on pyFM's descriptors (--data matrix:...)"
        for refine in none icp zoomout; do
            funcorr_match funcorrx "$refine" "$dir" "matrix:$dir/pyfm/descr_x.npy,$dir/pyfm/descr_y.npy" "$x" "$y"
        done
    fi

    cut -d' ' -f1-3 /proc/loadavg >>"$dir/loadavg"

    # evaluation jobs: (dir, tag, stage, map)
    for tag in funcorr funcorrx; do
        for stage in fmap icp zoomout; do
            refine=$stage; [[ $stage == fmap ]] && refine=none
            m=$dir/${tag}_$refine/map.txt
            [[ -f $m ]] && echo "$dir $xn $yn $tag $stage $m" >>"$EVAL_LIST"
        done
    done
    for v in $PYFM_VARIANTS; do
        name=${v%%=*}
        for stage in fmap icp zoomout; do
            m=$dir/pyfm/$name.$stage.map.txt
            [[ -f $m ]] && echo "$dir $xn $yn pyfm-$name $stage $m" >>"$EVAL_LIST"
        done
    done
done
T_TIMED=$(now)
log "timed runs done in $(elapsed "$T_START" "$T_TIMED") s; evaluating $(wc -l <"$EVAL_LIST") maps x 2 (sym, non-sym) with $EVAL_JOBS jobs"

# --- evaluation (untimed; parallel) -----------------------------------------------------------------
eval_one() {  # dir xn yn tag stage map
    local dir=$1 xn=$2 yn=$3 tag=$4 stage=$5 map=$6 kind
    for kind in sym nonsym; do
        local sym=()
        [[ $kind == sym ]] && sym=(--gt-target-sym "$DATA/corres/$yn.sym.vts")
        if ! "$FUNCORR_BIN" eval --source "$DATA/$xn.off" --target "$DATA/$yn.off" --map "$map" \
                --gt-source "$DATA/corres/$xn.vts" --gt-target "$DATA/corres/$yn.vts" "${sym[@]}" \
                --geodesics "$GEODESICS" --json >"$dir/eval.$tag.$stage.$kind.json" 2>"$dir/eval.$tag.$stage.$kind.stderr"; then
            echo "[bench] eval failed: $dir/eval.$tag.$stage.$kind.stderr" >&2
            rm -f "$dir/eval.$tag.$stage.$kind.json"
        fi
    done
}
export -f eval_one
export FUNCORR_BIN DATA GEODESICS
xargs -P "$EVAL_JOBS" -L 1 bash -c 'eval_one "$@"' _ <"$EVAL_LIST"
log "evaluation done in $(elapsed "$T_TIMED" "$(now)") s"

# --- rows and table ---------------------------------------------------------------------------------
ROWS=()
for pair in "${PAIR_LIST[@]}"; do
    read -r xn yn <<<"$pair"
    dir=$OUT/pyfm/${xn}_$yn
    "$PY" bench/pyfm_pipeline.py row --dir "$dir" --x "$DATA/$xn.off" --y "$DATA/$yn.off" --out "$dir/row.json"
    ROWS+=("$dir/row.json")
done
{
    echo "Command: \`SKIP_BUILD=$SKIP_BUILD FUNCORR_BIN=$FUNCORR_BIN PAIRS_N=${#PAIR_LIST[@]} bash bench/pyfm_stages.sh\`" \
        "(K $K, K_PROCESS $K_PROCESS, FUNCORR_DATA $FUNCORR_DATA, ICP_NIT $ICP_NIT, ZO_NIT $ZO_NIT, ZO_STEP $ZO_STEP," \
        "PYFM_VARIANTS \"$PYFM_VARIANTS\", INTRINSIC $INTRINSIC, CROSS $CROSS, GEODESICS $GEODESICS)"
    echo
    echo "funcorr: \`funcorr match X.off Y.off --method fmap --data $FUNCORR_DATA -k $K --kprime $K_PROCESS --refine {none,icp,zoomout}" \
        "--icp-iterations $ICP_NIT --zoomout-to $ZO_TO --zoomout-step $ZO_STEP --no-render --no-cache\` (one process per refinement)."
    echo
} >"$OUT/pyfm_table.md.head"
"$PY" bench/pyfm_pipeline.py table --env "$OUT/pyfm/env.json" --out "$OUT/pyfm_results.json" \
    --md "$OUT/pyfm_table.md.body" "${ROWS[@]}" >/dev/null
cat "$OUT/pyfm_table.md.head" "$OUT/pyfm_table.md.body" >"$OUT/pyfm_table.md"
rm -f "$OUT/pyfm_table.md.head" "$OUT/pyfm_table.md.body"
cat "$OUT/pyfm_table.md"
log "total $(elapsed "$T_START" "$(now)") s; table: $OUT/pyfm_table.md, raw results: $OUT/pyfm_results.json"
