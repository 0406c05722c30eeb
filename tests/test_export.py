import numpy as np
import pytest
import torch

from pchc_rsl.export import OnnxPolicy, export_onnx
from pchc_rsl.modules import GatedMoEActor, PCIActor, PreferenceMLPModel
from test_models import GAUSSIAN, GROUPS, make_obs


@pytest.mark.parametrize("actor_class", [PCIActor, GatedMoEActor, PreferenceMLPModel])
def test_onnx_matches_torch_with_a_dynamic_batch(tmp_path, actor_class):
    obs = make_obs()
    actor = actor_class(obs, GROUPS, "actor", 3, hidden_dims=[32, 16], obs_normalization=True,
                        distribution_cfg=GAUSSIAN)
    actor.update_normalization(make_obs(n=50, seed=3))  # non-trivial normaliser statistics
    path = export_onnx(actor, str(tmp_path / "policy.onnx"))
    policy = OnnxPolicy(path)
    for batch in (1, 64):
        o = make_obs(n=batch, seed=batch)
        with torch.no_grad():
            expected = actor(o).numpy()
        got = policy(o["policy"].numpy(), o["preference"].numpy())
        np.testing.assert_allclose(got, expected, atol=1e-5)


def test_onnx_policy_rejects_wrong_shapes_and_preferences(tmp_path):
    obs = make_obs()
    path = export_onnx(PCIActor(obs, GROUPS, "actor", 3, hidden_dims=[8]), str(tmp_path / "p.onnx"))
    policy = OnnxPolicy(path)
    good_obs = np.zeros((2, 24), np.float32)
    with pytest.raises(ValueError, match=r"obs must have shape \[B, 24\]"):
        policy(np.zeros((2, 23), np.float32), np.full((2, 2), 0.5, np.float32))
    with pytest.raises(ValueError, match="preference must have shape"):
        policy(good_obs, np.full((3, 2), 0.5, np.float32))
    with pytest.raises(ValueError, match="sum to 1"):
        policy(good_obs, np.full((2, 2), 0.7, np.float32))
