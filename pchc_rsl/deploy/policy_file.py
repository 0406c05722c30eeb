"""The exported policy's self-description, read without loading the network or torch, so that pchc-deploy checks
its arguments (preference, command, rates) against the file within a second, before anything else starts."""

from __future__ import annotations

import json

from pchc_rsl.export.metadata import METADATA_KEY
from pchc_rsl.export.onnx_session import open_onnx_session


def read_metadata(path: str) -> dict:
    """The deploy metadata of an ONNX policy file; ValueError in one line for anything else."""
    session = open_onnx_session(path)
    text = session.get_modelmeta().custom_metadata_map.get(METADATA_KEY)
    if text is None:
        raise ValueError(f"{path} lacks the deploy metadata (joints, gains, observation layout) a deploy needs; "
                         f"re-export it: pchc-export-onnx CHECKPOINT.pt -o {path} --force")
    meta = json.loads(text)
    if "action_scale_eta" not in meta or "joint_range" not in meta:
        raise ValueError(f"{path} lacks the action scale and joint ranges a deploy needs; re-export it: "
                         f"pchc-export-onnx CHECKPOINT.pt -o {path} --force")
    return meta
