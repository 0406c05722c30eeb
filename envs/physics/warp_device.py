"""Whether MuJoCo Warp can run on a CUDA device here, and how (CUDA graphs or eagerly), said before anything is built.

The warp-lang wheels on PyPI are built with a CUDA 13 toolkit and need an R580-series (CUDA 13) driver; on an older
driver Warp sees no CUDA device at all and the first allocation fails with "Invalid device identifier: cuda:0".
``require_warp_cuda`` turns that into a message with the versions found and the wheel to install instead.
"""

from __future__ import annotations

import importlib.metadata

import torch

TESTED_MUJOCO_WARP = ("4.0.0",)
"""mujoco-warp versions this project is tested with (warp_mujoco.py reads a private helper of it)."""

GRAPH_MIN_VERSION = (12, 4)
"""CUDA driver and toolkit needed for conditional CUDA graphs (the solver's early exit inside a captured step)."""


def _version(version) -> str:
    return "none" if version is None else ".".join(str(v) for v in version)


def warp_cuda_problem(device: str) -> str | None:
    """Why Warp cannot use ``device`` (a CUDA device), or None when it can."""
    import warp as wp

    wp.init()
    index = torch.device(device).index or 0
    count = wp.get_cuda_device_count()
    if count > index:
        return None
    driver, toolkit = wp.get_cuda_driver_version(), wp.get_cuda_toolkit_version()
    torch_cuda = torch.version.cuda or "none (a CPU build)"
    torch_sees = torch.cuda.device_count() if torch.cuda.is_available() else 0
    problem = (f"MuJoCo Warp cannot run on {device}: Warp {wp.__version__} sees {count} CUDA device(s) (torch, built "
               f"with CUDA {torch_cuda}, sees {torch_sees}). Warp was built with CUDA toolkit {_version(toolkit)}; the "
               f"CUDA driver here is {_version(driver)}.")
    if count:
        return problem + f" Pick a device Warp sees (cuda:0 .. cuda:{count - 1})."
    if driver is None:
        return problem + " No CUDA driver was found: install the NVIDIA driver, or train on the CPU (--physics mujoco)."
    if toolkit is not None and driver[0] < toolkit[0]:  # minor versions of one major are compatible
        return problem + (f" The driver is older than Warp's toolkit: install the CUDA 12 build of warp-lang (the "
                          f"'+cu12' wheel of warp-lang {wp.__version__} from github.com/NVIDIA/warp/releases: pip "
                          f"install warp_lang-{wp.__version__}+cu12-py3-none-manylinux_2_28_x86_64.whl), or update "
                          f"the driver to the R580 series or newer.")
    return problem


def require_warp_cuda(device: str) -> None:
    """Raise RuntimeError with ``warp_cuda_problem``'s explanation when Warp cannot use this CUDA device."""
    problem = warp_cuda_problem(device)
    if problem is not None:
        raise RuntimeError(problem)


def cuda_graph_problem(wp_device) -> str | None:
    """Why the physics should run eagerly rather than as captured CUDA graphs on this Warp device (None: capture).

    Capturing needs memory pools (a graph's allocations come from them) and conditional graph nodes (driver and
    toolkit >= 12.4), as mjlab requires before it captures."""
    import warp as wp

    if not wp_device.is_cuda:
        return "not a CUDA device"
    reasons = []
    if not wp.is_mempool_supported(wp_device):
        reasons.append("memory pools are not supported")
    driver, toolkit = wp.get_cuda_driver_version(), wp.get_cuda_toolkit_version()
    if driver is None or driver < GRAPH_MIN_VERSION or toolkit is None or toolkit < GRAPH_MIN_VERSION:
        reasons.append(f"conditional graphs need CUDA >= {_version(GRAPH_MIN_VERSION)} (driver {_version(driver)}, "
                       f"toolkit {_version(toolkit)})")
    return "; ".join(reasons) or None


def mujoco_warp_version_note() -> str | None:
    """A warning line when the installed mujoco-warp is not one this project was tested with."""
    try:
        installed = importlib.metadata.version("mujoco-warp")
    except importlib.metadata.PackageNotFoundError:
        return None
    if installed in TESTED_MUJOCO_WARP:
        return None
    return (f"mujoco-warp {installed} is not a version pchc-rsl was tested with ({', '.join(TESTED_MUJOCO_WARP)}); "
            f"if the Warp physics fails, install one: pip install mujoco-warp=={TESTED_MUJOCO_WARP[-1]}")
