"""Before the GPU check spends minutes: can this machine train on MuJoCo Warp at all? One line per requirement.

    python tools/gpu/gpu_preflight.py [--device cuda:0]

Checks the NVIDIA driver (nvidia-smi), torch's CUDA build and devices, Warp's CUDA devices (with what to install when
Warp's toolkit is newer than the driver), CUDA graph support, the mujoco-warp version, and the G1 model
(MENAGERIE_ROOT on a machine without internet). Exits 1 naming every requirement that failed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys


def driver_line() -> tuple[bool, str]:
    if shutil.which("nvidia-smi") is None:
        return False, "nvidia-smi not found: no NVIDIA driver installed here"
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version", "--format=csv,noheader"],
                             capture_output=True, text=True, timeout=30)
    except subprocess.TimeoutExpired:
        return False, "nvidia-smi did not answer within 30 s"
    if out.returncode != 0:
        return False, f"nvidia-smi failed: {(out.stderr or out.stdout).strip()[:200]}"
    gpus = [line.strip() for line in out.stdout.splitlines() if line.strip()]
    return bool(gpus), f"{len(gpus)} GPU(s): {'; '.join(gpus)}" if gpus else "nvidia-smi lists no GPU"


def torch_line(device: str) -> tuple[bool, str]:
    import torch

    build = torch.version.cuda
    if build is None:
        return False, (f"torch {torch.__version__} is a CPU build: install a CUDA build of torch (e.g. from the "
                       "wheelhouse: pip install --no-index --find-links DIR torch)")
    if not torch.cuda.is_available():
        return False, f"torch {torch.__version__} (CUDA {build}) sees no CUDA device: the driver is missing or too old"
    index = torch.device(device).index or 0
    if index >= torch.cuda.device_count():
        return False, f"torch sees {torch.cuda.device_count()} CUDA device(s); {device} is not one of them"
    return True, f"torch {torch.__version__}, CUDA {build}, {torch.cuda.get_device_name(index)}"


def warp_lines(device: str) -> list[tuple[bool, str]]:
    try:
        import warp as wp

        import mujoco_warp  # noqa: F401
    except ImportError as error:
        return [(False, f"MuJoCo Warp is not installed ({error}): pip install -e '.[warp]' (offline: pip install "
                        "--no-index --find-links WHEELHOUSE -e '.[warp]')")]
    from pchc_rsl.envs.physics.warp_device import cuda_graph_problem, mujoco_warp_version_note, warp_cuda_problem

    wp.config.quiet = True
    problem = warp_cuda_problem(device)
    if problem is not None:
        return [(False, problem)]
    lines = [(True, f"Warp {wp.__version__} sees {wp.get_cuda_device_count()} CUDA device(s) (toolkit "
                    f"{wp.get_cuda_toolkit_version()}, driver {wp.get_cuda_driver_version()})")]
    graphs = cuda_graph_problem(wp.get_device(device))
    lines.append((True, "CUDA graphs: captured" if graphs is None else f"CUDA graphs: off, runs eagerly ({graphs})"))
    note = mujoco_warp_version_note()
    lines.append((True, note or "mujoco-warp: a tested version"))  # a warning, not a refusal
    return lines


def model_line() -> tuple[bool, str]:
    root = os.environ.get("MENAGERIE_ROOT")
    try:
        from pchc_rsl.robots.g1.model import load_g1_spec

        load_g1_spec()
    except Exception as error:  # noqa: BLE001 - any failure means the same: no model here
        hint = "" if root else " (offline: set MENAGERIE_ROOT to a mujoco_menagerie checkout)"
        return False, f"the G1 model does not load: {str(error).splitlines()[0][:200]}{hint}"
    return True, f"the G1 model loads (MENAGERIE_ROOT={root or 'unset: downloaded cache'})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cuda:0")
    args = parser.parse_args(argv)
    checks = [("driver", driver_line()), ("torch", torch_line(args.device))]
    checks += [("warp", line) for line in warp_lines(args.device)]
    checks.append(("model", model_line()))
    for name, (ok, text) in checks:
        print(f"preflight {'ok  ' if ok else 'FAIL'} {name:6s} {text}", flush=True)
    failed = [name for name, (ok, _) in checks if not ok]
    if failed:
        print(f"preflight: refused: {', '.join(dict.fromkeys(failed))} not ready; nothing else was run", flush=True)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
