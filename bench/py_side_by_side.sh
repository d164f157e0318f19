#!/usr/bin/env bash
# funcorr-py beside pyFM per stage, and batch throughput local vs Ray (issue 14): see
# bench/py_side_by_side.py. Creates/reuses bench/.venv with bench/requirements-pyfm.txt (as
# bench/pyfm_side_by_side.sh does), installs funcorr from ./python (with Ray) into it, and runs
# the comparison on the first PAIRS pairs of $SHARED/data/faust_r.
#
#     bash bench/py_side_by_side.sh                 # 5 pairs
#     PAIRS=2 NO_RAY=1 bash bench/py_side_by_side.sh
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
SHARED=${SHARED:-../shared}
PAIRS=${PAIRS:-5}
OUT=${OUT:-bench/out/py_side_by_side}
VENV=bench/.venv
REQ=bench/requirements-pyfm.txt
if [[ ! -x $VENV/bin/python ]] || ! cat bench/requirements.txt "$REQ" | cmp -s - "$VENV/.requirements-pyfm.installed"; then
    [[ -x $VENV/bin/python ]] || python3 -m venv "$VENV"
    "$VENV/bin/pip" install --disable-pip-version-check -q -r "$REQ" >&2
    cat bench/requirements.txt "$REQ" >"$VENV/.requirements-pyfm.installed"
fi
"$VENV/bin/pip" install --disable-pip-version-check -q "./python[ray]" >&2
extra=()
[[ ${NO_RAY:-0} == 1 ]] && extra=(--no-ray)
"$VENV/bin/python" bench/py_side_by_side.py --data "$SHARED/data/faust_r" --pairs "$PAIRS" --out "$OUT" "${extra[@]}"
