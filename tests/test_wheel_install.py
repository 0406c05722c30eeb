"""The wheel, as a user installs it: built from this tree, it holds every module; installed (not editable) into a
fresh venv that borrows this venv's dependencies, it runs from outside the source tree: every console script's
--help (and each subcommand's), then the toy's train -> export -> eval -> play, and pchc-runs on the toy's run (slow,
a minute or two; .ci/run runs it).

Every other test imports the editable install, which finds any package in the tree whether the wheel holds it or not."""

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CONSOLE_SCRIPTS = {"pchc-train", "pchc-export-onnx", "pchc-eval", "pchc-play", "pchc-deploy", "pchc-sim-bridge",
                   "pchc-runs"}
"""The commands the README and docs name (the test fails when the wheel declares another)."""
SUBCOMMANDS = {"pchc-runs": ("average", "curves", "release")}
"""The commands of the console scripts that have them."""

NOT_SOURCE = shutil.ignore_patterns(".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache",
                                    "logs", "runs", "eval")

ONNX_MATCHES_TORCH = """
import sys
import numpy as np
import onnxruntime as ort
import torch

import pchc_rsl
from pchc_rsl.runners import load_checkpoint
from pchc_rsl.training.build import make_runner, restore_config, saved_config

checkpoint, onnx_file = sys.argv[1:]
cfg = restore_config(saved_config(checkpoint, load_checkpoint(checkpoint)))
cfg.num_envs, cfg.device = 1, "cpu"
runner = make_runner(cfg)
runner.load(checkpoint)
module = runner.alg.get_policy().as_onnx().eval()
session = ort.InferenceSession(onnx_file, providers=["CPUExecutionProvider"])
generator = torch.Generator().manual_seed(0)
obs = torch.randn(32, session.get_inputs()[0].shape[1], generator=generator)
lam = torch.rand(32, session.get_inputs()[1].shape[1], generator=generator)
lam = lam / lam.sum(-1, keepdim=True)
with torch.no_grad():
    expected = module(obs, lam).numpy()
actual = session.run(["actions"], {"obs": obs.numpy(), "preference": lam.numpy()})[0]
print(pchc_rsl.__file__)
print(float(np.abs(actual - expected).max()), float(np.abs(expected).max()))
"""


def outside_env(**extra: str) -> dict:
    """This process's environment without anything that would import from this tree instead."""
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return {**env, **extra}


def run(command: list[str], cwd: Path, env: dict) -> str:
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, f"{' '.join(command)}\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result.stdout


MAPPED_FOLDERS = ("envs", "robots", "configs")
"""Top-level folders installed as pchc_rsl.<folder>."""


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel of a copy of this tree (the build writes build/ and *.egg-info where it runs, not here)."""
    tmp_path = tmp_path_factory.mktemp("wheel")
    source = tmp_path / "source"
    shutil.copytree(ROOT, source, ignore=NOT_SOURCE)
    run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q",
         "-w", str(tmp_path / "dist"), str(source)], tmp_path, outside_env())
    (wheel,) = (tmp_path / "dist").glob("pchc_rsl-*.whl")
    return wheel


def dependency_folders() -> list[str]:
    """The site-packages folders this interpreter imports from, in order: its own and any that a .pth line added (a
    venv that itself borrows another's). The source tree is not one of them."""
    return [path for path in sys.path if Path(path).name in ("site-packages", "dist-packages") and Path(path).is_dir()]


def fresh_venv(tmp_path: Path, wheel: Path) -> Path:
    """A venv holding only the wheel; this venv's site-packages is on its path (a .pth line, which adds the folder
    but runs none of the .pth files in it, so the editable install's finder stays off): no download."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    site = Path(run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp_path,
                    outside_env()).strip())
    (site / "borrowed_dependencies.pth").write_text("\n".join(dependency_folders()) + "\n")
    run([str(python), "-m", "pip", "install", "--no-deps", "--no-index", "--ignore-installed", "-q", str(wheel)],
        tmp_path, outside_env())
    return venv


def wheel_scripts(wheel: Path) -> set[str]:
    """The console scripts the wheel declares (its entry_points.txt)."""
    with zipfile.ZipFile(wheel) as archive:
        (name,) = [n for n in archive.namelist() if n.endswith(".dist-info/entry_points.txt")]
        text = archive.read(name).decode()
    section = text.split("[console_scripts]")[1].split("\n[")[0]
    return {line.split("=")[0].strip() for line in section.splitlines() if "=" in line}


def test_the_wheel_holds_every_module_of_the_tree(wheel):
    in_tree = {f"pchc_rsl/{path.relative_to(ROOT / 'pchc_rsl').as_posix()}"
               for path in (ROOT / "pchc_rsl").rglob("*.py")}
    in_tree |= {f"pchc_rsl/{path.relative_to(ROOT).as_posix()}" for folder in MAPPED_FOLDERS
                for path in (ROOT / folder).rglob("*.py")}
    with zipfile.ZipFile(wheel) as archive:
        in_wheel = {name for name in archive.namelist() if name.endswith(".py")}
    assert {"pchc_rsl/evaluation/checkpoint.py", "pchc_rsl/envs/g1/env.py", "pchc_rsl/robots/g1/model.py"} <= in_tree
    missing = sorted(in_tree - in_wheel)
    assert not missing, f"the wheel lacks {len(missing)} modules of the tree: {missing}"
    assert not [name for name in in_wheel if name.split("/")[0] in MAPPED_FOLDERS]  # nothing generic at the top


@pytest.mark.slow
def test_the_wheel_installed_in_a_fresh_venv_runs_every_command_and_the_toy_from_train_to_video(wheel, tmp_path):
    assert wheel_scripts(wheel) == CONSOLE_SCRIPTS
    venv = fresh_venv(tmp_path, wheel)
    work = tmp_path / "elsewhere"  # outside the source tree: nothing importable from the current folder
    work.mkdir()
    env = outside_env(PATH=f"{venv / 'bin'}{os.pathsep}{os.environ['PATH']}", VIRTUAL_ENV=str(venv), MPLBACKEND="Agg")

    where = run(["python", "-c", "import pchc_rsl, shutil; print(pchc_rsl.__file__); print(shutil.which('pchc-eval'))"],
                work, env).split()
    assert all(Path(p).resolve().is_relative_to(venv.resolve()) for p in where), where  # not the editable install

    for script in sorted(CONSOLE_SCRIPTS):
        assert "usage:" in run([script, "--help"], work, env), script
        for command in SUBCOMMANDS.get(script, ()):
            assert f"usage: {script} {command} " in run([script, command, "--help"], work, env)

    run(["pchc-train", "--task", "toy", "--num-envs", "16", "--max-iterations", "2", "--log-dir", "run"], work, env)
    checkpoint = work / "run" / "model_1.pt"
    assert checkpoint.is_file()
    run(["pchc-export-onnx", str(checkpoint), "-o", "run/policy.onnx"], work, env)
    assert (work / "run" / "policy.onnx").stat().st_size > 1000
    module_file, difference, scale = run(["python", "-c", ONNX_MATCHES_TORCH, str(checkpoint), "run/policy.onnx"],
                                         work, env).split()
    assert Path(module_file).resolve().is_relative_to(venv.resolve())
    assert float(scale) > 0 and float(difference) < 1e-5, (difference, scale)
    run(["pchc-eval", str(checkpoint), "--preferences", "2", "--episodes", "1", "--num-envs", "4",
         "--output", "run/eval"], work, env)
    assert sorted(os.listdir(work / "run" / "eval")) == ["pareto.png", "results.json", "table.md"]
    run(["pchc-play", str(checkpoint), "--video", "run/toy.gif", "--preference", "1,0", "--seconds", "1"], work, env)
    assert (work / "run" / "toy.gif").read_bytes()[:6] == b"GIF89a"

    run(["pchc-runs", "average", "run/model_0.pt", "run/model_1.pt", "--out", "run/averaged.pt"], work, env)
    run(["pchc-runs", "release", "run/averaged.pt", "--name", "toy", "--out", "policies"], work, env)
    assert sorted(os.listdir(work / "policies")) == ["toy.onnx", "toy.pt"]
    run(["pchc-runs", "curves", "run", "--out", "run/curves.png"], work, env)
    assert (work / "run" / "curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
