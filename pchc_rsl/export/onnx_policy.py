"""An exported policy run in onnxruntime, with its inputs checked before they reach the session: what a robot runs
and what the exporter checks its file with."""

from __future__ import annotations

import json

import numpy as np
import onnxruntime as ort

from pchc_rsl.export.metadata import METADATA_KEY
from pchc_rsl.export.onnx_session import open_onnx_session
from pchc_rsl.preference import SUM_TOLERANCE, validate_preference


class OnnxPolicy:
    """An exported policy in onnxruntime: ``actions = policy(obs, preference)`` with the inputs checked up front
    (shapes, a non-empty batch, finite observations, each preference row on the simplex)."""

    def __init__(self, path: str, num_threads: int | None = None) -> None:
        options = ort.SessionOptions()
        if num_threads is not None:
            options.intra_op_num_threads = num_threads
            options.inter_op_num_threads = 1
        self.session = open_onnx_session(path, options)
        inputs = {i.name: i.shape for i in self.session.get_inputs()}
        if set(inputs) != {"obs", "preference"}:
            raise ValueError(f"{path} has inputs {list(inputs)}; a PCHC policy has 'obs' and 'preference'.")
        self.obs_dim = int(inputs["obs"][1])
        self.num_objectives = int(inputs["preference"][1])
        self.path = path
        self._metadata = self.session.get_modelmeta().custom_metadata_map.get(METADATA_KEY)

    @property
    def metadata(self) -> dict:
        """What a deploy needs (task, joints in order, kp, kd, effort limits, default pose, action scale, the
        observation layout, the control period, objectives); ValueError for a file exported without it."""
        if self._metadata is None:
            raise ValueError(f"{self.path} was exported before policies carried their deploy metadata; re-export "
                             f"it: pchc-export-onnx CHECKPOINT.pt -o {self.path} --force")

        return json.loads(self._metadata)

    def __call__(self, obs: np.ndarray, preference: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        preference = np.asarray(preference, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"obs must have shape [B, {self.obs_dim}], got {list(obs.shape)}.")
        if obs.shape[0] == 0:
            raise ValueError(f"obs has no rows (shape {list(obs.shape)}); give at least one observation.")
        if preference.ndim != 2 or preference.shape != (obs.shape[0], self.num_objectives):
            raise ValueError(
                f"preference must have shape [{obs.shape[0]}, {self.num_objectives}] (one row per obs row), "
                f"got {list(preference.shape)}."
            )
        bad_obs = ~np.isfinite(obs)
        if bad_obs.any():
            row, column = (int(i[0]) for i in np.nonzero(bad_obs))
            raise ValueError(
                f"obs row {row} holds {obs[row, column]} at column {column} ({int(bad_obs.any(1).sum())} of "
                f"{obs.shape[0]} rows are not finite); observations must be finite numbers."
            )
        self._check_preference_rows(preference)
        return self.session.run(["actions"], {"obs": obs, "preference": preference})[0]

    def _check_preference_rows(self, preference: np.ndarray) -> None:
        """Raise for the first row off the simplex, naming it (not the whole batch); vectorised for large batches."""
        finite = np.isfinite(preference).all(axis=1)
        sums = np.where(finite, preference.sum(axis=1), np.nan)
        ok = finite & (preference >= 0).all(axis=1) & (np.abs(sums - 1.0) <= SUM_TOLERANCE)
        if not ok.all():
            row = int(np.argmin(ok))
            try:
                validate_preference(preference[row], self.num_objectives)
            except ValueError as error:
                raise ValueError(
                    f"preference row {row} ({int((~ok).sum())} of {preference.shape[0]} rows are bad): {error}"
                ) from None
