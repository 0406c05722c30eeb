#!/usr/bin/env bash
# The GPU check: can this machine train pchc-rsl on MuJoCo Warp, how fast, and within Warp's buffers? One verdict line.
#
#     bash tools/gpu_check.sh [--wheelhouse DIR] [--step-timeout SECONDS] [--device cuda:0]
#
# Needs a CUDA build of torch; no internet: with --wheelhouse DIR the project and its warp extra are installed from
# that folder of wheels first (pip install --no-index --find-links DIR -e '.[warp]'). Set MENAGERIE_ROOT to a
# mujoco_menagerie checkout and PCHC_MOTION_DIR to the G1 clips (AMP smoke run) on a machine without internet.
#   0. preflight (tools/gpu_preflight.py): driver, torch's CUDA build, Warp's CUDA devices, CUDA graphs, the G1
#      model; refuses with what is missing, before anything slow runs
#   1. MuJoCo Warp against C MuJoCo at Warp's solver settings (tools/warp_parity.py)
#   2. the real runner.learn at 4096 and 8192 envs: steps/s, collection and learning time, host syncs per env step,
#      the largest constraint rows, solver iterations and contacts (an overflow fails) (tools/gpu_learn_check.py)
#   3. fall-recovery smoke run (pchc-train, 2 iterations)
#   4. AMP smoke run (pchc-train with the LAFAN1 walk, 2 iterations; skipped without PCHC_MOTION_DIR)
#   5. torchrun with 2 ranks when 2 GPUs are there
# Each step runs under its own timeout. The last line is the verdict: "gpu_check: PASS ...", "gpu_check: FAIL ..." or
# "gpu_check: NOT RUN ..." (the preflight refused).
set -uo pipefail
cd "$(dirname "$0")/.."

wheelhouse="" step_timeout=600 device="cuda:0"
while [ $# -gt 0 ]; do
    case "$1" in
        --wheelhouse) wheelhouse="${2:?--wheelhouse needs a folder}"; shift 2 ;;
        --step-timeout) step_timeout="${2:?--step-timeout needs seconds}"; shift 2 ;;
        --device) device="${2:?--device needs a CUDA device}"; shift 2 ;;
        -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
        *) echo "gpu_check: unknown option '$1' (allowed: --wheelhouse DIR, --step-timeout SECONDS, --device cuda:N)"
           exit 2 ;;
    esac
done

passed=() failed=() skipped=()
step() {  # step NAME COMMAND...: run it under the timeout, record the outcome
    local name="$1"; shift
    echo "== $name"
    local start=$SECONDS
    timeout --kill-after=30 "$step_timeout" "$@"
    local rc=$?
    if [ $rc -eq 0 ]; then passed+=("$name"); echo "-- $name: ok ($((SECONDS - start)) s)"
    elif [ $rc -eq 124 ] || [ $rc -eq 137 ]; then failed+=("$name (timed out after ${step_timeout} s)")
    else failed+=("$name (exit $rc)"); fi
}

if [ -n "$wheelhouse" ]; then
    if [ ! -d "$wheelhouse" ]; then
        echo "gpu_check: NOT RUN: --wheelhouse $wheelhouse is not a folder"; exit 2
    fi
    echo "== install from $wheelhouse (no index)"
    if ! pip install --no-index --find-links "$wheelhouse" -e ".[warp]"; then
        echo "gpu_check: NOT RUN: the wheelhouse lacks a wheel the project needs (see pip's message above)"; exit 2
    fi
fi

echo "== 0. preflight"
if ! timeout 120 python tools/gpu_preflight.py --device "$device"; then
    echo "gpu_check: NOT RUN: the preflight refused (see its lines above); nothing was measured"
    exit 1
fi

step "1. Warp against C MuJoCo" python tools/warp_parity.py --device "$device" --num-envs 64 --steps 20
motions=()
if [ -n "${PCHC_MOTION_DIR:-}" ] && [ -f "$PCHC_MOTION_DIR/lafan1_walk1_subject1.csv" ]; then
    motions=(--motion-files "$PCHC_MOTION_DIR/lafan1_walk1_subject1.csv")
fi
step "2. runner.learn at 4096 and 8192 envs" python tools/gpu_learn_check.py --device "$device" \
    --num-envs 4096 8192 --iterations 3 "${motions[@]}"
runs="$(mktemp -d)"
step "3. fall-recovery smoke" python -m pchc_rsl.cli.train --task g1-fall-recovery --physics warp \
    --device "$device" --num-envs 1024 --max-iterations 2 --log-dir "$runs/fall"
if [ ${#motions[@]} -gt 0 ]; then
    step "4. AMP smoke" python -m pchc_rsl.cli.train --task g1-walk-fast --physics warp --device "$device" \
        --num-envs 1024 --max-iterations 2 --log-dir "$runs/amp" "${motions[@]}"
else
    skipped+=("4. AMP smoke (set PCHC_MOTION_DIR)")
fi
if [ "$(python -c 'import torch; print(torch.cuda.device_count())')" -ge 2 ]; then
    step "5. torchrun, 2 ranks" torchrun --standalone --nproc_per_node=2 -m pchc_rsl.cli.train --task g1-walk-fast \
        --physics warp --device cuda --num-envs 1024 --max-iterations 2 --log-dir "$runs/torchrun"
else
    skipped+=("5. torchrun (one GPU; needs two)")
fi
rm -rf "$runs"

summary="${#passed[@]} passed"
[ ${#skipped[@]} -gt 0 ] && summary="$summary, skipped: $(IFS=';'; echo "${skipped[*]}")"
if [ ${#failed[@]} -eq 0 ]; then
    echo "gpu_check: PASS ($summary)"
else
    echo "gpu_check: FAIL ($(IFS=';'; echo "${failed[*]}"); $summary)"
    exit 1
fi
