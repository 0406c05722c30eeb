"""A fixed-seed rollout of both G1 tasks matches, bit for bit, the digests recorded from the env before it was split
into its parts (tests/g1_rollout_digest.py): moving code must not change a number. A quantity added since (a new
metric) is not compared; every recorded one must still be there."""

import json

import pytest

from g1_rollout_digest import DIGEST_FILE, TASKS, rollout_digests
from test_g1_env import g1_available

pytestmark = pytest.mark.skipif(not g1_available(), reason="G1 model unavailable (set MENAGERIE_ROOT)")


def recorded() -> dict:
    with open(DIGEST_FILE) as f:
        return json.load(f)


def same_libraries(versions: dict) -> bool:
    import mujoco
    import torch

    return versions == {"torch": torch.__version__, "mujoco": mujoco.__version__}


@pytest.mark.parametrize("task", TASKS)
def test_rollout_is_bit_identical_to_the_recorded_one(task):
    data = recorded()
    if not same_libraries(data["versions"]):
        pytest.skip(f"digests recorded with {data['versions']}; other torch or MuJoCo builds round differently "
                    "(re-record on unchanged env code with python tests/g1_rollout_digest.py --write)")
    expected = data["tasks"][task]
    got = rollout_digests(task, names=list(expected["quantities"]))
    first = next((i for i, (a, b) in enumerate(zip(expected["steps"], got["steps"])) if a != b), None)
    differing = sorted(k for k in expected["quantities"].keys() | got["quantities"].keys()
                       if expected["quantities"].get(k) != got["quantities"].get(k))
    assert first is None and not differing, f"{task}: first differs at step {first}; quantities: {differing}"


def test_the_digest_sees_a_one_ulp_change():
    import torch

    from g1_rollout_digest import digest

    x = torch.tensor([0.1, 0.2], dtype=torch.float32)
    y = x.clone()
    y[1] = torch.nextafter(y[1], torch.tensor(1.0))
    assert digest(x) != digest(y) and digest(x) == digest(x.clone())
