"""The README's and the docs' commands run as written, in order, in a fresh folder (slow: trains the toy task a few
times), and .ci/run calls the README's test command."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def section(title: str, path: Path = README) -> str:
    text = path.read_text()
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


def code_lines(text: str) -> list[str]:
    """Indented (4-space) code lines, comments after '#' dropped."""
    lines = [line[4:] for line in text.splitlines() if line.startswith("    ") and not line.startswith("     ")]
    return [re.sub(r"\s+#.*$", "", line).rstrip() for line in lines]


def run(command: str, cwd: Path) -> str:
    env = {**os.environ, "PATH": os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"]}
    result = subprocess.run(command, shell=True, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, f"{command}\n{result.stdout[-2000:]}\n{result.stderr[-2000:]}"
    return result.stdout


def test_the_first_two_commands_set_up_and_run_the_main_job_and_the_tests():
    setup_and_train, setup_and_test = code_lines(section("Quickstart"))[:2]
    assert setup_and_train.startswith("python3 -m venv") and " pchc-train --task toy " in setup_and_train
    assert 'pip install -e . ' in setup_and_train, "the main job installs what training needs, not [dev]"
    assert setup_and_test.startswith("python3 -m venv") and setup_and_test.endswith("python -m pytest -q -rs")
    assert 'pip install -e ".[dev]"' in setup_and_test
    ci = (ROOT / ".ci" / "run").read_text()
    assert setup_and_test.split(" && ")[-1] in ci.splitlines()  # CI runs the README's test command


@pytest.mark.slow
def test_the_quickstart_and_the_training_guide_run_as_written(tmp_path):
    quickstart = section("Quickstart")
    train = code_lines(quickstart)[0].split(" && ")[-1]  # this venv is already set up
    toy = [line for line in code_lines(quickstart) if line.startswith("pchc-") and "logs/toy" in line]
    assert len(toy) == 4
    outputs = [run(command, tmp_path) for command in [train, *toy]]
    assert (tmp_path / "logs/toy/model_59.pt").is_file() and (tmp_path / "logs/toy-more/model_79.pt").is_file()
    assert sorted(os.listdir(tmp_path / "logs/toy/eval")) == ["pareto.png", "results.json", "table.md"]
    assert "logs/toy/model_59.pt" in outputs[0]  # the summary names the real checkpoint
    guide = ROOT / "docs" / "training.md"
    snippet = "\n".join(line for line in code_lines(section("Export", guide))
                        if not line.startswith(("pchc-", "python", "pip")))
    run(f"{sys.executable} - <<'EOF'\n{snippet}\nassert actions.shape == (4, 2)\nEOF", tmp_path)
    for title in ("Continue a run, or start from its weights", "Changing the config: `KEY=VALUE`"):
        for line in code_lines(section(title, guide)):
            if line.startswith("pchc-train --task toy"):
                run(line, tmp_path)
    assert (tmp_path / "logs/toy-custom/model_59.pt").is_file() and (tmp_path / "logs/toy-tuned").is_dir()
    for line in code_lines(section("After training: `pchc-runs`", guide)):
        run(line, tmp_path)
    assert sorted(os.listdir(tmp_path / "logs/policies")) == ["toy.onnx", "toy.pt"]
    assert (tmp_path / "logs/toy-curves.png").read_bytes()[:4] == b"\x89PNG"
