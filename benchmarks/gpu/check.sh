#!/usr/bin/env bash
# One-command GPU check (issue 31): the `gpu` tests, the learners' updates/s (eager vs captured),
# end-to-end training frames/s, and (issue 47) one-env end-to-end frames/s on MO-Gymnasium cases (the
# machine's CPU; MORL-Baselines beside it where its venv exists); ONE table at the end. Every stage has
# its own time limit and writes its rows as it goes, so a hang or a failure leaves the others' results.
# The one-env cases need mo-gymnasium among the carried wheels:
#   ../shared/tools/device-wheels.sh mo-gymnasium==1.3.2
#
#   benchmarks/gpu/check.sh                      # on a machine with one NVIDIA GPU (<= 9 min wall)
#   benchmarks/gpu/check.sh --device cpu --tiny  # the CPU dry run the test suite runs (tests/gpu)
#
# Output: the table on stdout and, with every log, under $OUT if set, else ./gpu-check-out/
# (summary.txt, table.tsv, env.txt, tests.log, losses.log, train.log: 6 files).
# With .whl/ present (../shared/tools/device-wheels.sh), the carried wheels are installed into
# /tmp/site first (no network). Exit status: 0 when every stage passed, 1 otherwise.
set -uo pipefail

DEVICE=cuda
TINY=0
while [ $# -gt 0 ]; do
  case "$1" in
    --device) DEVICE="$2"; shift 2 ;;
    --device=*) DEVICE="${1#*=}"; shift ;;
    --tiny) TINY=1; shift ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "check.sh: unknown argument '$1' (valid: --device cpu|cuda, --tiny)" >&2; exit 2 ;;
  esac
done
case "$DEVICE" in cpu|cuda) ;; *) echo "check.sh: --device must be cpu or cuda, got '$DEVICE'" >&2; exit 2 ;; esac

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
OUTDIR="${OUT:-$ROOT/gpu-check-out}"
mkdir -p "$OUTDIR"
TABLE="$OUTDIR/table.tsv"
: > "$TABLE"
PY="${PYTHON:-python3}"
START=$SECONDS

# tensordict's PyTree registration breaks CudaGraphModule; unbuffered: partial logs survive a kill
export EXCLUDE_TD_FROM_PYTREE=1 PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1
if compgen -G ".whl/*.whl" > /dev/null; then
  "$PY" -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl \
    && export PYTHONPATH="/tmp/site:$ROOT" || echo "check.sh: installing .whl/ failed" >&2
else
  export PYTHONPATH="$ROOT${PYTHONPATH:+:$PYTHONPATH}"
fi

# Time limits (seconds) per stage; the sum stays under 8 minutes with the wheel install.
if [ "$TINY" = 1 ]; then
  # hang guards, not speed limits: each stage is a few CPU-seconds of work (2 x 16 networks, batches
  # of 16, one thread) plus imports, ~30 s in all on a free CPU and ~2 min on a loaded 2-core one
  T_TESTS=600 T_LOSSES=600 T_TRAIN=600 T_ONE_ENV=600
  TEST_SELECT=(-k "cpu-envelope")            # one learner and one capture case prove the stage runs
  LOSS_ARGS=(--tiny --peer none)
  TRAIN_ARGS=(--tiny --peer none)
  PAIRS=(envelope:MOLavaGridDR-v0)
  ONE_ENV_ARGS=(envelope-dst --one-env-frames 30 --peer none)
else
  # measured on one H200 (2026-11-27): tests 23 s, losses 21 s, a train pair 20 s eager+graphs plus
  # ~30 s per compiled variant, the compiled losses ~35 s per method
  T_TESTS=60 T_LOSSES=45 T_LOSSES_COMPILED=90 T_TRAIN_PAIR=80 T_ONE_ENV=90
  if [ "$DEVICE" = cuda ]; then TEST_SELECT=(-k cuda); else TEST_SELECT=(); fi
  LOSS_ARGS=(--updates 100 --rounds 2 --min-round-seconds 0 --peer none)   # a GPU update takes ms: time enough of them (a fixed count: the stage has its time limit)
  TRAIN_ARGS=(--frames 512 --peer none)
  PAIRS=(envelope:MOLunarLanderDR-v0 envelope:MOLavaGridDR-v0 capql:MOHopperDR-v5)
  # the two methods furthest below MB on one env (docs/speed.md), 1,000 frames each, process CPU time
  ONE_ENV_ARGS=(envelope-dst gpi_ls-dst --one-env-frames 1000 --clock cpu)
fi
if [ "$DEVICE" = cuda ]; then
  # captured rows in order of interest; "whole": sampling + update + priority writes in one graph
  # (Envelope's prioritized replay); elsewhere the compiled variant is "both" (compile + graphs)
  LOSS_ARGS+=(--capture cudagraphs whole)
fi
train_capture() {  # the captured variants timed end to end for one algorithm
  [ "$DEVICE" = cuda ] || return 0
  if [ "${1%%:*}" = envelope ]; then echo --capture cudagraphs whole whole+compile
  else echo --capture cudagraphs both; fi
}

STATUS=0
stage() {  # stage NAME SECONDS LOG CMD...: runs CMD under a time limit, appending to LOG
  local name=$1 limit=$2 log=$3; shift 3
  local t0=$SECONDS
  echo "== $name (limit ${limit}s): $*" | tee -a "$log"
  timeout -k 5 "$limit" "$@" >> "$log" 2>&1
  local rc=$?
  local took=$((SECONDS - t0))
  if [ $rc -eq 124 ] || [ $rc -eq 137 ]; then
    echo "== $name: TIMEOUT after ${took}s (partial results kept)" | tee -a "$log"
    printf 'stage\t%s\t%s\t-\ttime\tTIMEOUT\t\t\tafter %ss\n' "$name" "$DEVICE" "$took" >> "$TABLE"
    STATUS=1
  elif [ $rc -ne 0 ]; then
    echo "== $name: FAILED (exit $rc) after ${took}s" | tee -a "$log"
    printf 'stage\t%s\t%s\t-\ttime\tFAILED\t\t\texit %s after %ss\n' "$name" "$DEVICE" "$rc" "$took" >> "$TABLE"
    STATUS=1
  else
    echo "== $name: ok in ${took}s" | tee -a "$log"
    printf 'stage\t%s\t%s\t-\ttime\tok\t\t\t%ss\n' "$name" "$DEVICE" "$took" >> "$TABLE"
  fi
  return 0
}

{
  date -u
  echo "device=$DEVICE tiny=$TINY root=$ROOT git=$(git rev-parse --short HEAD 2>/dev/null || echo '?')"
  command -v nvidia-smi > /dev/null && nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
  timeout 60 "$PY" -c "import torch, torchrl, tensordict; print('torch', torch.__version__, '| torchrl', torchrl.__version__, \
'| tensordict', tensordict.__version__, '| cuda', torch.cuda.is_available() and torch.cuda.get_device_name(0))"
} > "$OUTDIR/env.txt" 2>&1
cat "$OUTDIR/env.txt"
if [ "$DEVICE" = cuda ] && ! timeout 60 "$PY" -c "import torch, sys; sys.exit(0 if torch.cuda.is_available() else 1)"; then
  echo "check.sh: --device cuda but torch sees no CUDA device" | tee -a "$OUTDIR/env.txt"
  STATUS=1
fi

# 1. the tests marked gpu (every learner and the trainer's loop on the device; captured == eager)
stage tests "$T_TESTS" "$OUTDIR/tests.log" \
  "$PY" -m pytest -q -p no:cacheprovider -m "gpu and not slow" tests/gpu "${TEST_SELECT[@]}" -o addopts="" -rfE
grep -E "^(FAILED|ERROR)|[0-9]+ (passed|failed)" "$OUTDIR/tests.log" | tail -12 \
  | while IFS= read -r line; do printf 'tests\tpytest -m gpu\t%s\t-\t-\t%s\t\t\t\n' "$DEVICE" "$line" >> "$TABLE"; done

# 2. updates/s of each learner, eager vs captured
stage losses "$T_LOSSES" "$OUTDIR/losses.log" \
  "$PY" benchmarks/bench_losses.py --device "$DEVICE" "${LOSS_ARGS[@]}" --table "$TABLE"

# 3. end to end, one process per pair (its own limit)
for pair in "${PAIRS[@]}"; do
  # shellcheck disable=SC2046  # train_capture's words are separate arguments
  stage "train $pair" "${T_TRAIN_PAIR:-$T_TRAIN}" "$OUTDIR/train.log" \
    "$PY" benchmarks/bench_train.py --device "$DEVICE" --pairs "$pair" "${TRAIN_ARGS[@]}" $(train_capture "$pair") --table "$TABLE"
done

# 4. end to end on one MO-Gymnasium env (issue 47): the loop a new user runs first, on this machine's CPU
stage "train one-env" "$T_ONE_ENV" "$OUTDIR/train.log" \
  "$PY" benchmarks/bench_train.py --one-env "${ONE_ENV_ARGS[@]}" --table "$TABLE"

# 5. the compiled updates last: compiling takes tens of seconds per variant
if [ "$DEVICE" = cuda ] && [ "$TINY" = 0 ]; then
  stage "losses compiled" "$T_LOSSES_COMPILED" "$OUTDIR/losses.log" \
    "$PY" benchmarks/bench_losses.py --device "$DEVICE" --updates 200 --rounds 1 --min-round-seconds 0 --peer none --capture whole+compile both --table "$TABLE"
fi

# the one table
"$PY" - "$TABLE" "$DEVICE" "$((SECONDS - START))" > "$OUTDIR/summary.txt" <<'EOF'
import sys
rows = [line.rstrip("\n").split("\t") for line in open(sys.argv[1]) if line.strip()]
print(f"benchmarks/gpu/check.sh --device {sys.argv[2]}: {sys.argv[3]} s wall")
head = ("stage", "what", "device", "variant", "unit", "value", "peer", "ratio", "note")
rows = [head] + [(r + [""] * 9)[:9] for r in rows]
width = [min(48, max(len(r[i]) for r in rows)) for i in range(9)]
for r in rows:
    print("  ".join(c[:48].ljust(w) for c, w in zip(r, width)).rstrip())
EOF
echo
cat "$OUTDIR/summary.txt"
echo "(logs and table under $OUTDIR)"
exit $STATUS
