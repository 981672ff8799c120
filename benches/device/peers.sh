#!/bin/bash
# The batch-1 float32 step against onnxruntime (benches/peers.py, paper bundle) on another CPU:
# the lent device machine's (docs/PERFORMANCE.md asks for a second CPU's figures). That machine
# has python3 with torch, onnx and onnxruntime, but no Rust, so troupe's `stream` is built here
# and carried. Prepare, in the repository root (`.devbench/` must be git-ignored):
#
#   cargo build --release --example stream
#   mkdir -p .devbench && cp benches/device/peers.sh .devbench/run.sh
#   strip -o /tmp/stream target/release/examples/stream && xz -c /tmp/stream > .devbench/stream.xz
#   cp onnx/bundles/paper/troupe.json .devbench/paper-troupe-local.json
#   (cd onnx/bundles/paper && sha256sum *.onnx peers/*.onnx) > .devbench/paper-local.sha256
#
# then one device call: command `set -o pipefail; LIMIT=468 bash .devbench/run.sh both 2>&1 |
# tee $OUT/log`, carry [".devbench"], timeout 480 s. The tracked tree is over the tool's 64 MiB
# (68.8 MiB on 2026-11-30): move `onnx/checkpoints/armflow-demo.pt` and
# `onnx/bundles/armflow-demo-int8` out of the tree for the call, and back after it.
#
# Usage: LIMIT=seconds bash .devbench/run.sh [native|avx2|both]; writes under $OUT.
set -o pipefail
MODE=${1:-both}
T0=$(date +%s)
LIMIT=${LIMIT:-400}
CORE=${CORE:-2}
B=${BUNDLE:-/tmp/paper}
PRESET=${PRESET:-paper}
HIST=${HISTORIES:-10,100,1000,2000}
REPEATS=${REPEATS:-5}
el() { echo $(( $(date +%s) - T0 )); }
say() { echo "== [$(el) s] $*"; }
REPO=$(pwd)
TS="taskset -c $CORE"; taskset -c $CORE true || { echo "taskset failed: running unpinned"; TS=""; }
export PYTHONUNBUFFERED=1 CUDA_VISIBLE_DEVICES=
say "machine"
lscpu
echo "nproc: $(nproc)"; uname -a; grep PRETTY /etc/os-release; ldd --version | head -1
grep -m1 "model name" /proc/cpuinfo; grep -m1 "^flags" /proc/cpuinfo
python3 -c "import sys, torch, onnx, onnxruntime, numpy; print(sys.executable, sys.version.split()[0], 'torch', torch.__version__, 'onnx', onnx.__version__, 'onnxruntime', onnxruntime.__version__, 'numpy', numpy.__version__)"
S=/tmp/troupe-stream
python3 -c "import lzma, shutil; shutil.copyfileobj(lzma.open('.devbench/stream.xz'), open('$S', 'wb'))" && chmod +x $S || exit 1
sha256sum $S
ldd $S
say "stream sanity on the tiny bundle"
$S --bundle onnx/bundles/armflow-tiny --synthetic --no-pictures --frames 8 --tick 4 --out /tmp/sanity.npy 2>&1 | tail -4 || exit 1
if [ -f $B/troupe.json ] && [ -f $B/peers/context_step.onnx ]; then
  say "paper bundle already at $B"
else
  say "export the paper bundle"
  rm -rf $B
  python3 onnx/cli.py armflow export --preset $PRESET --out $B --peer-graphs || exit 1
  say "exported"
fi
du -sh $B
python3 -c "import json; print('producer device:', json.load(open('$B/troupe.json'))['producer'], 'local:', json.load(open('.devbench/paper-troupe-local.json'))['producer'])"
cmp -s $B/troupe.json .devbench/paper-troupe-local.json && echo "manifest identical to the local one" || echo "manifest differs from the local one"
(cd $B && sha256sum -c $REPO/.devbench/paper-local.sha256 2>&1 | sed 's/^/onnx digest vs local: /') 
cp $B/troupe.json $OUT/paper-troupe-device.json
# Size the run to the time left: on the 2-core dev EPYC (probe p50 8.2 ms) the full native run
# (4 histories, 5 repeats) took 374 s; scale by this CPU's probe and keep a 15 % margin.
say "speed probe: paper bundle, capacity 101, 20 warm-up + 40 timed tokens, core $CORE"
P=$($TS $S --bundle $B --synthetic --no-pictures --capacity 101 --warmup-tokens 20 --frames 240 --tick 4 --out /tmp/probe.npy | tee /dev/stderr | sed -n 's/.*produced a token (40 calls): p50 \([0-9.]*\) ms.*/\1/p')
echo "probe p50: $P ms"
plan() {  # seconds left -> sets REPEATS (and HIST if it must drop 2000)
  local left=$1
  local per=$(python3 -c "print(int(374 / 5 * ${P:-20} / 8.2 * 1.15) + 1)")
  local r=$(( left / per )); [ $r -gt $REPEATS ] && r=$REPEATS
  RUN_REPEATS=$r
  echo "plan: ${per} s per repetition predicted, ${left} s left -> repeats $r, histories $HIST"
  [ $r -ge 3 ]
}
bench() {  # isa json
  local left=$(( LIMIT - $(el) - 5 ))
  if ! plan $left; then
    if [ "$1" = avx2 ]; then say "avx2 skipped: too little time"; return 3; fi
    RUN_REPEATS=3; HIST=10,100,1000; echo "native reduced: repeats 3, histories $HIST"
  fi
  say "peers.py --isa $1 (timeout ${left} s), pinned to core $CORE"
  timeout -k 5 $left $TS python3 benches/peers.py --bundle $B --histories $HIST \
    --steps 20 --repeats $RUN_REPEATS --peers ort --troupe-binary $S --isa $1 --json $OUT/$2
  local rc=$?; say "peers.py --isa $1 rc=$rc"; return $rc
}
if [ "$MODE" != avx2 ]; then
  t=$(el); bench native peers-native.json; rc=$?; dur=$(( $(el) - t ))
  say "native took $dur s"
  if [ "$MODE" = both ]; then
    if [ $rc -eq 0 ]; then bench avx2 peers-avx2.json; else say "avx2 skipped: native failed"; fi
  fi
else
  bench avx2 peers-avx2.json
fi
say "done"
