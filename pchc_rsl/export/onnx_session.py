"""Opening an exported policy file in onnxruntime with errors that say what the file is instead (a PyTorch
checkpoint, a truncated or foreign file). Imports neither torch nor the rest of pchc_rsl, so a deploy can read a
file's metadata within a second."""

from __future__ import annotations

import onnxruntime as ort


def open_onnx_session(path: str, options=None):
    """An onnxruntime InferenceSession on the CPU; ValueError in one line for a file that is not a readable ONNX
    model."""
    with open(path, "rb") as f:
        magic = f.read(2)
    if magic == b"PK":  # a zip archive: what torch.save writes
        raise ValueError(f"{path} is a PyTorch checkpoint, not an ONNX file; export it first: pchc-export-onnx "
                         f"{path} -o policy.onnx")
    try:
        return ort.InferenceSession(path, options, providers=["CPUExecutionProvider"])
    except Exception as error:  # noqa: BLE001 - onnxruntime's INVALID_PROTOBUF and friends
        reason = (str(error).strip().splitlines() or [type(error).__name__])[0][:160]
        raise ValueError(f"{path} is not a readable ONNX file (truncated or another format?): {reason}") from None
