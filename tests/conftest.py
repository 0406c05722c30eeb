import pytest

from pchc_rsl.configs import task_config

G1_SKIP = "G1 model unavailable (set MENAGERIE_ROOT)"
"""The reason every test that needs the G1 model gives when it skips; the run's last line counts them."""


def g1_skip_line(skip_reasons: list[str]) -> str | None:
    """The line that ends a test run in which G1 tests were skipped (None if none were): how many, why, the fix."""
    skipped = sum(G1_SKIP in reason for reason in skip_reasons)
    if not skipped:
        return None
    return (f"{skipped} of {len(skip_reasons)} skipped tests need the Unitree G1 model, which was not found: set "
            "MENAGERIE_ROOT to a folder holding unitree_g1/g1_mjlab.xml (or go online: mujoco-menagerie downloads "
            "it on first use) to run them.")


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """After pytest's own summary: the one line on skipped G1 tests."""
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is None:
        return
    reasons = [report.longrepr[2] for report in reporter.stats.get("skipped", [])
               if isinstance(report.longrepr, tuple) and len(report.longrepr) == 3]
    line = g1_skip_line(reasons)
    if line:
        reporter.write_line(line)


@pytest.fixture
def toy_cfg():
    """The toy task, small."""
    cfg = task_config("toy")
    cfg.num_envs = 8
    return cfg


@pytest.fixture(scope="module")
def walk_checkpoint(tmp_path_factory):
    """A one-iteration g1-walk-fast checkpoint (2 envs), shared by a test module."""
    from test_g1_env import g1_available

    if not g1_available():
        pytest.skip(G1_SKIP)
    from pchc_rsl.cli import train

    log_dir = tmp_path_factory.mktemp("walk")
    train.main(["--task", "g1-walk-fast", "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(log_dir)])
    return str(log_dir / "model_0.pt")
