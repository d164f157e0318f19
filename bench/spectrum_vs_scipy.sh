#!/usr/bin/env bash
# Benchmark: `funcorr spectrum` vs scipy.sparse.linalg.eigsh (shift-invert, sigma=-0.01)
# on the same cotangent Laplacian, on real meshes. Prints a Markdown table (for BENCHMARKS.md)
# on stdout, progress on stderr, raw results in bench/out/spectrum_results.json.
#
# Run from the repository root:
#     bash bench/spectrum_vs_scipy.sh
#     KS="50 100" SHAPES="../shared/data/faust_r/tr_reg_000.off" bash bench/spectrum_vs_scipy.sh
#
# Environment knobs:
#   SHARED=../shared     where shared/ lives (default shapes are under $SHARED/data/)
#   SHAPES="a.off b.off" shapes to run (default: FAUST tr_reg_000 ~5k, TOSCA cat0 28k, david0 52k)
#   KS="50 100 200 350"  numbers of eigenpairs
#   REPEATS=3            timed runs per (shape, k) for funcorr and for each scipy BLAS configuration;
#                        the fastest is reported
#   SIGMA=-0.01          eigsh shift
#   OUT=bench/out        output folder
#   FUNCORR_BIN=target/release/funcorr   binary to benchmark
#   SKIP_BUILD=1         don't run `cargo build --release`
#   CHECK_LAPLACIAN=0    skip the cross-check of funcorr's W/mass against bench/cotan_laplacian.py
# scipy is run in two BLAS configurations per repeat: OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1, and the
# library default (those variables unset: 2 threads on a 2-CPU machine); the table reports the faster.
# Needs GNU time (/usr/bin/time -v) and python3 (>= 3.11, with venv).
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."

SHARED=${SHARED:-../shared}
DEFAULT_SHAPES="$SHARED/data/faust_r/tr_reg_000.off $SHARED/data/tosca_hires/cat0.off $SHARED/data/tosca_hires/david0.off"
SHAPES=${SHAPES:-$DEFAULT_SHAPES}
KS=${KS:-"50 100 200 350"}
REPEATS=${REPEATS:-3}
SIGMA=${SIGMA:--0.01}
OUT=${OUT:-bench/out}
FUNCORR_BIN=${FUNCORR_BIN:-target/release/funcorr}
SKIP_BUILD=${SKIP_BUILD:-0}
CHECK_LAPLACIAN=${CHECK_LAPLACIAN:-1}
VENV=bench/.venv
PY=$VENV/bin/python

log() { echo "[bench] $*" >&2; }
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.6f", b - a }'; }

# --- prerequisites ------------------------------------------------------------------------------
if ! /usr/bin/time -v true >/dev/null 2>&1; then
    echo "error: GNU time (/usr/bin/time -v) is required for wall time and peak RSS." >&2
    echo "       Install it with:  apt-get update && apt-get install -y time" >&2
    exit 1
fi
if ! command -v python3 >/dev/null || ! python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    echo "error: python3 >= 3.11 (with the venv module) is required for the pinned numpy/scipy" >&2
    exit 1
fi

# --- python virtualenv (numpy, scipy pinned in bench/requirements.txt) ---------------------------
if [[ ! -x $PY ]] || ! cmp -s bench/requirements.txt "$VENV/.requirements.installed"; then
    log "setting up $VENV from bench/requirements.txt"
    [[ -x $PY ]] || python3 -m venv "$VENV"
    "$VENV/bin/pip" install --disable-pip-version-check -q -r bench/requirements.txt >&2
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

load1=$(cut -d' ' -f1 /proc/loadavg)
if awk -v l="$load1" 'BEGIN { exit !(l > 0.5) }'; then
    log "WARNING: 1-minute load average is $load1: other processes are using the CPUs, timings will be noisy"
fi

mkdir -p "$OUT/rows"
"$PY" bench/compare_spectra.py env --out "$OUT/env.json" --funcorr-bin "$FUNCORR_BIN"
log "machine: $(lscpu | sed -n 's/^Model name:[[:space:]]*//p'), $(nproc) CPUs;" \
    "$("$PY" -c 'import numpy, scipy; print("numpy", numpy.__version__, "scipy", scipy.__version__)')"

for shape in $SHAPES; do
    if [[ ! -f $shape ]]; then
        echo "error: shape $shape not found (set SHARED=... or SHAPES=...)" >&2
        exit 1
    fi
done
read -r -a KLIST <<<"$KS"
if [[ ${#KLIST[@]} == 0 ]]; then
    echo "error: KS is empty" >&2
    exit 1
fi

ROWS=()
for shape in $SHAPES; do
    name=$(basename "$shape" .off)
    key=$(basename "$(dirname "$shape")")_$name   # unique per data set folder
    dir=$OUT/$key
    mkdir -p "$dir"
    lap=$dir/lap.npz
    rm -f "$lap"

    # Untimed preparatory run: writes W and mass for scipy (and warms the page cache).
    kprep=${KLIST[0]}
    log "$name: funcorr spectrum -k $kprep --save-laplacian (untimed, produces the matrices for scipy)"
    if "$FUNCORR_BIN" spectrum "$shape" -k "$kprep" -o "$dir/prep.npz" --no-cache \
            --save-laplacian "$lap" >"$dir/prep.stdout" 2>"$dir/prep.stderr"; then
        :
    else
        log "$name: preparatory funcorr run failed (exit $?), see $dir/prep.stderr"
    fi

    for k in "${KLIST[@]}"; do
        rm -f "$dir/funcorr_k$k".* "$dir/scipy_k$k".*
        # -- funcorr, timed (without --save-laplacian); one stderr file per repeat (stage timings)
        fargs=() ; frc=0
        for ((r = 1; r <= REPEATS; r++)); do
            ferr=$dir/funcorr_k$k.r$r.stderr
            fargs+=(--funcorr-stderr "$ferr")
            t0=$(now)
            if /usr/bin/time -v -o "$dir/funcorr_k$k.r$r.time" \
                    "$FUNCORR_BIN" spectrum "$shape" -k "$k" -o "$dir/funcorr_k$k.npz" --no-cache \
                    >"$dir/funcorr_k$k.stdout" 2>"$ferr"; then
                t1=$(now)
                fargs+=(--funcorr-wall "$(elapsed "$t0" "$t1")" --funcorr-time "$dir/funcorr_k$k.r$r.time")
            else
                frc=$?
                log "$name k=$k: funcorr failed (exit $frc), see $ferr"
                break
            fi
        done

        # -- scipy eigsh on funcorr's matrices, in both BLAS configurations; the order alternates
        #    between repeats so that neither configuration always runs first.
        sargs=()
        declare -A src=([1]=0 [default]=0)
        if [[ -f $lap ]]; then
            for ((r = 1; r <= REPEATS; r++)); do
                if ((r % 2)); then cfgs=(1 default); else cfgs=(default 1); fi
                for cfg in "${cfgs[@]}"; do
                    [[ ${src[$cfg]} == 0 ]] || continue   # this configuration already failed
                    if [[ $cfg == 1 ]]; then
                        tenv=(env OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1)
                    else
                        tenv=(env -u OPENBLAS_NUM_THREADS -u OMP_NUM_THREADS -u GOTO_NUM_THREADS)
                    fi
                    stem=$dir/scipy_k$k.t$cfg.r$r
                    if "${tenv[@]}" /usr/bin/time -v -o "$stem.time" \
                            "$PY" bench/scipy_eigsh.py "$lap" "$k" --sigma="$SIGMA" --json "$stem.json" \
                            >/dev/null 2>"$stem.stderr"; then
                        sargs+=(--scipy-run "$cfg" "$stem.json" "$stem.time")
                    else
                        src[$cfg]=$?
                        log "$name k=$k: scipy ($cfg BLAS threads) failed (exit ${src[$cfg]}), see $stem.stderr"
                    fi
                done
            done
            sargs+=(--scipy-rc 1 "${src[1]}" --scipy-rc default "${src[default]}")
        fi  # no LAP.npz: scipy is skipped and the row reports "no scipy result"

        check=()
        [[ $CHECK_LAPLACIAN == 1 ]] && check=(--check-laplacian)
        row=$OUT/rows/${key}_k$k.json
        "$PY" bench/compare_spectra.py row --name "$name" --shape "$shape" --k "$k" --lap "$lap" \
            --out "$row" --funcorr-out "$dir/funcorr_k$k.npz" --funcorr-rc "$frc" \
            ${fargs[@]+"${fargs[@]}"} ${sargs[@]+"${sargs[@]}"} ${check[@]+"${check[@]}"}
        ROWS+=("$row")
    done
done

# The table step exits 2 when a row failed: the table is still printed, and so is the exit status.
set +e
"$PY" bench/compare_spectra.py table --env "$OUT/env.json" --out "$OUT/spectrum_results.json" "${ROWS[@]}" \
    | tee "$OUT/spectrum_table.md"
rc=${PIPESTATUS[0]}
set -e
log "raw results: $OUT/spectrum_results.json, table: $OUT/spectrum_table.md"
[[ $rc == 0 ]] || log "some rows failed (exit $rc)"
exit "$rc"
