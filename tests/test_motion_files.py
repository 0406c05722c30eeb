"""A broken .npz motion clip gives one line naming the file, not numpy's BadZipFile."""

import numpy as np
import pytest

from pchc_rsl.amp.motion import load_motion


@pytest.fixture
def clip(tmp_path):
    path = tmp_path / "walk.npz"
    np.savez(path, fps=np.array(50.0), dof_names=np.array(["a_joint", "b_joint"]),
             dof_positions=np.random.default_rng(0).normal(size=(200, 2)))
    return path


def test_a_good_clip_loads(clip):
    assert tuple(load_motion(clip, ["b_joint"], 50.0).shape) == (200, 1)


@pytest.mark.parametrize("damage, message", [
    (lambda b: b[: len(b) // 2], "is not a readable .npz archive"),
    (lambda b: b"", r"\(0 bytes\) is not a readable .npz archive"),
    (lambda b: b"hello" * 20, "is not a readable .npz archive"),
])
def test_a_damaged_clip_is_named_in_one_line(clip, damage, message):
    clip.write_bytes(damage(clip.read_bytes()))
    with pytest.raises(ValueError, match=message) as error:
        load_motion(clip, ["b_joint"], 50.0)
    assert str(clip) in str(error.value) and "\n" not in str(error.value)
