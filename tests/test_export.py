import numpy as np
import pytest
import torch

from pchc_rsl.export.onnx_export import export_onnx
from pchc_rsl.export.onnx_policy import OnnxPolicy
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


def test_a_g1_policy_file_describes_itself_for_a_deploy(tmp_path):
    """The walker's ONNX carries the task, joints in order with kp / kd / effort limits from the G1's constants,
    the default pose, the action scale (0.25 x effort / kp per joint), an observation layout whose size is the
    policy's input, and the control period; a file exported without it is refused in one line naming the fix."""
    import os

    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip("G1 model unavailable (set MENAGERIE_ROOT)")
    from pchc_rsl.cli import export_onnx as export_cli
    from pchc_rsl.export.onnx_policy import OnnxPolicy
    from pchc_rsl.robots.g1.constants import WALK_JOINTS, joint_gains, joint_motor
    from pchc_rsl.robots.g1.model import default_joint_positions

    walker = os.path.join(os.path.dirname(__file__), "..", "policies", "g1_walk.pt")
    path = str(tmp_path / "walk.onnx")
    export_cli.main([walker, "-o", path])
    policy = OnnxPolicy(path)
    meta = policy.metadata
    assert meta["task"] == "g1-walk-fast" and meta["joint_names"] == list(WALK_JOINTS)
    assert meta["kp"] == pytest.approx([joint_gains(j)[0] for j in WALK_JOINTS])
    assert meta["kd"] == pytest.approx([joint_gains(j)[1] for j in WALK_JOINTS])
    assert meta["effort_limit"] == pytest.approx([joint_motor(j).effort_limit for j in WALK_JOINTS])
    assert meta["default_joint_pos"] == pytest.approx(list(default_joint_positions(list(WALK_JOINTS))), abs=1e-6)
    assert meta["action_scale"] == pytest.approx(
        [0.25 * joint_motor(j).effort_limit / joint_gains(j)[0] for j in WALK_JOINTS], rel=1e-5)
    assert meta["observation"]["frames"] * meta["observation"]["frame_dim"] == policy.obs_dim == 420
    assert meta["control_period_s"] == pytest.approx(0.02)
    assert meta["objective_names"] == ["disturbance", "stride"] and meta["preference_size"] == 2
    old = str(tmp_path / "old.onnx")
    import onnx

    model = onnx.load(path)
    del model.metadata_props[:]
    onnx.save(model, old)
    with pytest.raises(ValueError, match=r"exported before .* re-export it: pchc-export-onnx CHECKPOINT.pt -o"):
        OnnxPolicy(old).metadata
