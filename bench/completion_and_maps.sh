#!/usr/bin/env bash
# Issue 4 and 5 benchmarks: the L1 kernel of the completion method (value + gradient, random
# bases, several block sizes), the subspace optimizer per iteration on a FAUST pair and on TOSCA
# cat0↔cat10, and the point-map conversions (nearest neighbours, ICP, ZoomOut 30→200).
#   bash bench/completion_and_maps.sh        # needs ../shared/data; writes nothing but stdout
# Knobs: SHARED (default ../shared), ITER_FAUST (default 300: run to convergence), ITER_CAT (default 3).
set -euo pipefail
cd "$(dirname "$0")/.."
SHARED=${SHARED:-../shared}
F=$SHARED/data/faust_r
C=$SHARED/data/tosca_hires
cargo build --release --examples -q
echo "# machine: $(nproc) CPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), load $(cut -d' ' -f1 /proc/loadavg), $(date -u +%F)"
echo "# commit $(git rev-parse --short HEAD)"
echo "## L1 kernel, m = n = 5000, k' = 350, k = 250 (paper scarce setting), block rows:"
for b in 128 256 512 1024; do ./target/release/examples/completion_timing 5000 5000 350 250 5 $b | tail -2 | sed "s/^/block $b: /"; done
echo "## L1 kernel, m = n = 5000, k' = 50, k = 30 (rich setting):"
./target/release/examples/completion_timing 5000 5000 50 30 5 512 | tail -2
echo "## L1 kernel, m = n = 27894 (cat), k' = 350, k = 250:"
./target/release/examples/completion_timing 27894 27894 350 250 2 512 | tail -2
echo "## subspace optimizer on faust_r tr_reg_000 -> tr_reg_001 (k' = 350, k = 250):"
./target/release/examples/completion_timing pair $F/tr_reg_000.off $F/tr_reg_001.off 350 250 "${ITER_FAUST:-300}"
echo "## subspace optimizer on tosca_hires cat0 -> cat10 (k' = 350, k = 250):"
./target/release/examples/completion_timing pair $C/cat0.off $C/cat10.off 350 250 "${ITER_CAT:-3}"
echo "## conversions, faust_r tr_reg_000 -> tr_reg_001:"
./target/release/examples/pointwise_timing $F/tr_reg_000.off $F/tr_reg_001.off $F/corres/tr_reg_000.vts $F/corres/tr_reg_001.vts $F/corres/tr_reg_001.sym.vts
echo "## conversions, tosca_hires cat0 -> cat10 (same vertex ids):"
ZOOMOUT_STEPS=5 ./target/release/examples/pointwise_timing $C/cat0.off $C/cat10.off identity
