"""The exported policy's self-description, read without loading the network or torch, so that pchc-deploy checks
its arguments (preference, command, rates) against the file within a second, before anything else starts."""

from __future__ import annotations

import json

METADATA_KEY = "pchc"  # pchc_rsl.export.METADATA_KEY, repeated here to keep torch out of this module


def read_metadata(path: str) -> dict:
    """The deploy metadata of an ONNX policy file; ValueError in one line for anything else."""
    with open(path, "rb") as f:
        magic = f.read(2)
    if magic == b"PK":  # a zip archive: what torch.save writes
        raise ValueError(f"{path} is a PyTorch checkpoint, not an ONNX file; export it first: pchc-export-onnx "
                         f"{path} -o policy.onnx")
    import onnxruntime as ort

    try:
        session = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    except Exception as error:  # noqa: BLE001 - onnxruntime's INVALID_PROTOBUF and friends
        reason = (str(error).strip().splitlines() or [type(error).__name__])[0][:160]
        raise ValueError(f"{path} is not a readable ONNX file (truncated or another format?): {reason}") from None
    text = session.get_modelmeta().custom_metadata_map.get(METADATA_KEY)
    if text is None:
        raise ValueError(f"{path} lacks the deploy metadata (joints, gains, observation layout) a deploy needs; "
                         f"re-export it: pchc-export-onnx CHECKPOINT.pt -o {path} --force")
    meta = json.loads(text)
    if "action_scale_eta" not in meta or "joint_range" not in meta:
        raise ValueError(f"{path} lacks the action scale and joint ranges a deploy needs; re-export it: "
                         f"pchc-export-onnx CHECKPOINT.pt -o {path} --force")
    return meta
