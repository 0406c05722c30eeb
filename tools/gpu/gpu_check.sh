#!/usr/bin/env bash
# The GPU check, run once on a new machine: can it train pchc-rsl on MuJoCo Warp, how fast, within Warp's buffers?
# A JSON summary and one verdict line.
#
#     bash tools/gpu/gpu_check.sh [--wheelhouse DIR] [--step-timeout SECONDS] [--device cuda:0] [--summary FILE]
#
# Needs a CUDA build of torch; no internet: with --wheelhouse DIR the project and its warp extra are installed from
# that folder of wheels first (pip install --no-index --find-links DIR -e '.[warp]'). Set MENAGERIE_ROOT to a
# mujoco_menagerie checkout and PCHC_MOTION_DIR to the G1 clips (AMP) on a machine without internet.
#   0. preflight (tools/gpu/gpu_preflight.py): driver, torch's CUDA build, Warp's CUDA devices, CUDA graphs, the G1
#      model; refuses with what is missing, before anything slow runs
#   1. the physics: MuJoCo Warp against C MuJoCo fed the same inputs (tools/gpu/warp_parity.py, 64 envs, 20 steps),
#      and its self-check (Warp's actuators 5% stronger must fail it)
#   2. runner.learn of g1-walk-fast, AMP on, at 4096, 8192 and 16384 envs, 10 iterations each
#      (tools/gpu/gpu_learn_check.py): steps/s, host syncs per env step and the lines making them, env.step against
#      physics.step, Warp's peaks and solver-limit share; an overflow fails
#   3. runner.learn of g1-fall-recovery at 4096 envs, 10 iterations
#   4. pchc-train under torchrun, one rank (and two ranks over NCCL where there are two GPUs)
# Each step runs under its own timeout. The summary (default gpu_check.json where the check was started) holds each
# step's outcome, seconds and figures. The last line is the verdict: "gpu_check: PASS ...", "gpu_check: FAIL ..." or
# "gpu_check: NOT RUN ..." (the preflight refused).
set -uo pipefail
started_in="$(pwd)"
cd "$(dirname "$0")/../.."

wheelhouse="" step_timeout=300 device="cuda:0" summary="$started_in/gpu_check.json"
while [ $# -gt 0 ]; do
    case "$1" in
        --wheelhouse) wheelhouse="${2:?--wheelhouse needs a folder}"; shift 2 ;;
        --step-timeout) step_timeout="${2:?--step-timeout needs seconds}"; shift 2 ;;
        --device) device="${2:?--device needs a CUDA device}"; shift 2 ;;
        --summary) summary="${2:?--summary needs a file}"; shift 2 ;;
        -h|--help) sed -n '2,23p' "$0"; exit 0 ;;
        *) echo "gpu_check: unknown option '$1' (allowed: --wheelhouse DIR, --step-timeout SECONDS, --device cuda:N," \
                "--summary FILE)"
           exit 2 ;;
    esac
done

out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
check_start=$SECONDS
steps_file="$out/steps.tsv"
: > "$steps_file"

record() {  # record NAME OUTCOME SECONDS [JSON FILE]
    printf '%s\t%s\t%s\t%s\n' "$1" "$2" "$3" "${4:-}" >> "$steps_file"
}

step() {  # step NAME JSON_FILE COMMAND...: run it under the timeout, record the outcome
    local name="$1" json="$2"; shift 2
    echo "== $name"
    local start=$SECONDS
    timeout --kill-after=30 "$step_timeout" "$@"
    local rc=$? outcome
    if [ $rc -eq 0 ]; then outcome="ok"
    elif [ $rc -eq 124 ] || [ $rc -eq 137 ]; then outcome="timed out after ${step_timeout} s"
    else outcome="failed (exit $rc)"; fi
    echo "-- $name: $outcome ($((SECONDS - start)) s)"
    record "$name" "$outcome" "$((SECONDS - start))" "$json"
}

expect_failure() {  # expect_failure NAME COMMAND...: a self-check, which passes when the command exits 1
    local name="$1"; shift
    echo "== $name"
    local start=$SECONDS
    timeout --kill-after=30 "$step_timeout" "$@" > "$out/self_check.log" 2>&1
    local rc=$? outcome
    tail -n 1 "$out/self_check.log"
    if [ $rc -eq 1 ]; then outcome="ok"; else outcome="failed (exit $rc, expected 1)"; fi
    echo "-- $name: $outcome ($((SECONDS - start)) s)"
    record "$name" "$outcome" "$((SECONDS - start))"
}

write_summary() {  # write_summary VERDICT: the JSON summary from the recorded steps and their JSON files
    python - "$summary" "$1" "$steps_file" "$((SECONDS - check_start))" "$device" <<'PY'
import json, os, sys
path, verdict, steps_file, seconds, device = sys.argv[1:6]
steps = []
for row in open(steps_file).read().splitlines():
    name, outcome, took, figures = (row.split("\t") + [""])[:4]
    step = {"step": name, "outcome": outcome, "seconds": int(took)}
    if figures and os.path.exists(figures):
        step["figures"] = json.load(open(figures))
    steps.append(step)
with open(path, "w") as f:
    json.dump({"verdict": verdict, "device": device, "seconds": int(seconds), "steps": steps}, f, indent=2)
PY
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
start=$SECONDS
if ! timeout 120 python tools/gpu/gpu_preflight.py --device "$device"; then
    record "0. preflight" "refused" "$((SECONDS - start))"
    write_summary "NOT RUN"
    echo "gpu_check: NOT RUN: the preflight refused (see its lines above); nothing was measured (summary: $summary)"
    exit 1
fi
record "0. preflight" "ok" "$((SECONDS - start))"

step "1. physics: Warp against C MuJoCo" "$out/parity.json" \
    python tools/gpu/warp_parity.py --device "$device" --num-envs 64 --steps 20 --json "$out/parity.json"
expect_failure "1b. the parity check fails on a different physics" \
    python tools/gpu/warp_parity.py --device "$device" --num-envs 64 --steps 5 --perturb-gains 0.05

motions=() amp="AMP on"
if [ -n "${PCHC_MOTION_DIR:-}" ] && [ -f "$PCHC_MOTION_DIR/lafan1_walk1_subject1.csv" ]; then
    motions=(--motion-files "$PCHC_MOTION_DIR/lafan1_walk1_subject1.csv")
else
    amp="AMP off: set PCHC_MOTION_DIR"
fi
step "2. runner.learn, g1-walk-fast ($amp), 4096 8192 16384 envs" "$out/learn_walk.json" \
    python tools/gpu/gpu_learn_check.py --device "$device" --task g1-walk-fast --num-envs 4096 8192 16384 \
    --iterations 10 "${motions[@]}" --json "$out/learn_walk.json"
step "3. runner.learn, g1-fall-recovery, 4096 envs" "$out/learn_fall.json" \
    python tools/gpu/gpu_learn_check.py --device "$device" --task g1-fall-recovery --num-envs 4096 --iterations 10 \
    --json "$out/learn_fall.json"

runs="$out/runs"
gpus="$(python -c 'import torch; print(torch.cuda.device_count())')"
step "4. torchrun, one rank" "" torchrun --standalone --nproc_per_node=1 -m pchc_rsl.cli.train --task g1-walk-fast \
    --physics warp --device cuda --num-envs 1024 --max-iterations 3 --log-dir "$runs/one_rank"
if [ "$gpus" -ge 2 ]; then
    step "4b. torchrun, two ranks over NCCL" "" torchrun --standalone --nproc_per_node=2 -m pchc_rsl.cli.train \
        --task g1-walk-fast --physics warp --device cuda --num-envs 1024 --max-iterations 3 --log-dir "$runs/nccl"
fi

failed="$(awk -F'\t' '$2 != "ok" {printf "%s%s: %s", sep, $1, $2; sep="; "}' "$steps_file")"
passed="$(awk -F'\t' '$2 == "ok"' "$steps_file" | wc -l)"
took=$((SECONDS - check_start))
notes=""
[ ${#motions[@]} -eq 0 ] && notes=", AMP off (set PCHC_MOTION_DIR)"
[ "$gpus" -lt 2 ] && notes="$notes, NCCL with two ranks not run (one GPU)"
if [ -z "$failed" ]; then
    write_summary "PASS"
    echo "gpu_check: PASS ($passed steps in $took s$notes; summary: $summary)"
else
    write_summary "FAIL"
    echo "gpu_check: FAIL ($failed; $passed steps passed in $took s$notes; summary: $summary)"
    exit 1
fi
