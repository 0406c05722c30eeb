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


@pytest.fixture
def exported(tmp_path):
    """A small PCI policy exported into its own folder, with the torch actor it came from."""
    actor = PCIActor(make_obs(), GROUPS, "actor", 3, hidden_dims=[8])
    folder = tmp_path / "export"
    export_onnx(actor, str(folder / "policy.onnx"))
    return actor, folder


def test_the_onnx_file_is_self_contained_and_alone(exported, tmp_path):
    import shutil

    actor, folder = exported
    assert sorted(p.name for p in folder.iterdir()) == ["policy.onnx"]  # no external data, no temp files
    robot = tmp_path / "robot"
    robot.mkdir()
    shutil.copy(folder / "policy.onnx", robot / "policy.onnx")
    o = make_obs(n=3, seed=5)
    with torch.no_grad():
        expected = actor(o).numpy()
    got = OnnxPolicy(str(robot / "policy.onnx"))(o["policy"].numpy(), o["preference"].numpy())
    np.testing.assert_allclose(got, expected, atol=1e-5)


def test_exports_get_the_umask_mode_not_0600(exported):
    import os

    umask = os.umask(0)
    os.umask(umask)
    _, folder = exported
    assert (folder / "policy.onnx").stat().st_mode & 0o777 == 0o666 & ~umask


def test_export_is_quiet(tmp_path, capfd):
    actor = PCIActor(make_obs(), GROUPS, "actor", 3, hidden_dims=[8])
    capfd.readouterr()
    export_onnx(actor, str(tmp_path / "p.onnx"))
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_export_refuses_non_finite_weights(tmp_path):
    actor = PCIActor(make_obs(), GROUPS, "actor", 3, hidden_dims=[8])
    with torch.no_grad():
        next(actor.parameters())[0, 0] = float("nan")
    with pytest.raises(ValueError, match="NaN or inf"):
        export_onnx(actor, str(tmp_path / "p.onnx"))
    assert not list(tmp_path.iterdir())


def test_onnx_policy_names_the_first_bad_input_row(exported):
    _, folder = exported
    policy = OnnxPolicy(str(folder / "policy.onnx"))
    lam = np.full((4096, 2), 0.5, np.float32)
    obs = np.zeros((4096, 24), np.float32)
    with pytest.raises(ValueError, match="no rows"):
        policy(np.zeros((0, 24), np.float32), np.zeros((0, 2), np.float32))
    bad_obs = obs.copy()
    bad_obs[17, 3] = np.inf
    bad_obs[20, 0] = np.nan
    with pytest.raises(ValueError, match="obs row 17 .*column 3 .*2 of 4096 rows"):
        policy(bad_obs, lam)
    bad_lam = lam.copy()
    bad_lam[1234] = (0.7, 0.7)
    with pytest.raises(ValueError, match=r"preference row 1234 \(1 of 4096 rows are bad\)") as error:
        policy(obs, bad_lam)
    assert len(str(error.value)) < 300
    assert policy(obs, lam).shape == (4096, 3)
