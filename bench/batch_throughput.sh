#!/usr/bin/env bash
# Batch throughput of the default pipeline over a whole data set (issue 30 item 6): the CLI's
# `funcorr bench --methods axiomatic`, `funcorr.batch.match_pairs` on the local engine and on
# Ray, every shape prepared once per run (see bench/batch_throughput.py).
#
#     bash bench/batch_throughput.sh                  # every pair of faust_r
#     PAIRS=4 NO_RAY=1 bash bench/batch_throughput.sh # quick check
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
SHARED=${SHARED:-../shared}
DATA=${DATA:-$SHARED/data/faust_r}
PAIRS=${PAIRS:-0}
OUT=${OUT:-bench/out/batch_throughput}
# PY=/path/to/python: an interpreter that has funcorr (this commit) and ray installed already,
# e.g. the CI's target/ci-venv/bin/python; else bench/.venv-batch is made from ./python.
if [[ -z ${PY:-} ]]; then
    VENV=bench/.venv-batch
    [[ -x $VENV/bin/python ]] || python3 -m venv "$VENV"
    "$VENV/bin/pip" install --disable-pip-version-check -q "./python[ray]" >&2
    PY=$VENV/bin/python
fi
cargo build --release >&2
extra=()
[[ ${NO_RAY:-0} == 1 ]] && extra=(--no-ray)
"$PY" bench/batch_throughput.py --data "$DATA" --pairs "$PAIRS" --out "$OUT" \
    --funcorr target/release/funcorr "${extra[@]}"
