#!/usr/bin/env bash
# The GPU check, one script for a user's GPU machine or a lent one, under 8 minutes on one GPU:
#   1. MuJoCo Warp on CUDA against C MuJoCo (tools/warp_parity.py),
#   2. the whole training loop on Warp at 1024 and 4096 envs, with the host syncs of one iteration counted by torch's
#      sync debug mode (tools/bench_train.py --sync-debug),
#   3. a 2-rank torchrun training smoke (NCCL, one GPU per rank) when two GPUs are there.
# Prints the figures; stops at the first failure. Needs the warp extra: pip install -e ".[warp]".
#     bash tools/gpu_check.sh
set -euo pipefail
cd "$(dirname "$0")/.."
python -c "import torch, sys; sys.exit(0 if torch.cuda.is_available() else 'gpu_check: torch sees no CUDA device')"
python -c "import torch; print('gpu_check:', torch.__version__, torch.cuda.get_device_name(0), torch.cuda.device_count(), 'GPU(s)')"
echo "== 1. Warp on CUDA against C MuJoCo"
python tools/warp_parity.py --device cuda:0 --num-envs 16 --steps 20
echo "== 2. training loop on Warp, 1024 and 4096 envs"
python tools/bench_train.py --physics warp --device cuda:0 --num-envs 1024 4096 --iterations 2 --sync-debug
if [ "$(python -c 'import torch; print(torch.cuda.device_count())')" -ge 2 ]; then
    echo "== 3. torchrun, 2 ranks"
    run="$(mktemp -d)/run"
    torchrun --standalone --nproc_per_node=2 -m pchc_rsl.cli.train --task g1-walk-fast --physics warp --device cuda \
        --num-envs 1024 --max-iterations 2 --log-dir "$run"
    ls "$run"
else
    echo "== 3. skipped: one GPU (the 2-rank smoke needs two)"
fi
echo "gpu_check: done"
