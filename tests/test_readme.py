"""The README's commands run as written, in order, in a fresh folder (slow: trains the toy task twice)."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def section(title: str) -> str:
    text = README.read_text()
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


@pytest.mark.slow
def test_the_quickstart_runs_as_written(tmp_path):
    quickstart = section("Quickstart")
    setup_and_train, setup_and_test = code_lines(quickstart)[:2]  # the README's first two commands
    assert setup_and_train.startswith("python3 -m venv") and setup_and_test.endswith("python -m pytest -q -rs")
    train = setup_and_train.split(" && ")[-1]  # this venv is already set up
    commands = [train] + [line for line in code_lines(quickstart) if line.startswith("pchc-")]
    assert len(commands) == 5
    outputs = [run(command, tmp_path) for command in commands]
    assert (tmp_path / "logs/toy/model_59.pt").is_file() and (tmp_path / "logs/toy-more/model_79.pt").is_file()
    assert sorted(os.listdir(tmp_path / "logs/toy/eval")) == ["pareto.png", "results.json", "table.md"]
    assert "logs/toy/model_59.pt" in outputs[0]  # the summary names the real checkpoint
    snippet = "\n".join(line for line in code_lines(quickstart) if not line.startswith(("pchc-", "python", "pip")))
    run(f"{sys.executable} - <<'EOF'\n{snippet}\nassert actions.shape == (4, 2)\nEOF", tmp_path)
    # the config section's commands that need no G1 model
    for line in code_lines(section("Train, export, evaluate")):
        if line.startswith("pchc-train --task toy") or "--show-config" in line:
            run(line, tmp_path)
    assert (tmp_path / "logs/toy-custom/model_59.pt").is_file()
