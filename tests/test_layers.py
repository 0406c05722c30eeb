"""The layers of the package. The command-line interfaces are the edge: library code (pchc_rsl, envs, robots, configs)
and the tools never import pchc_rsl.cli, so everything a CLI does can be called from Python without parsing
arguments. Below the edge each package imports only the packages beneath it (LAYERS), so none imports another that
imports it back."""

import ast
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
LIBRARY = ["pchc_rsl", "envs", "robots", "configs", "tools", "examples"]
MAPPED = ("envs", "robots", "configs")
"""Top-level folders installed as pchc_rsl.<folder>."""

LAYERS = [
    "utils",  # what knows nothing of PCHC
    "preference", "pareto",  # the paper's math
    "storage", "modules", "amp", "algorithms",  # the learning, laid out as rsl-rl's
    "export",  # the ONNX file a robot runs
    "runners",
    "robots", "envs", "configs",  # the MuJoCo side
    "training",  # a training job from a config
    "evaluation",
    "viewers",
    "deploy",
    "cli",
]
"""pchc_rsl's packages (and its two loose modules), lowest first: each may import only those before it."""


def cli_imports(path: pathlib.Path) -> list[str]:
    """'line: module' for every import of pchc_rsl.cli (or a module in it) in one file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module is not None:
            names = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        else:
            continue
        found += [f"{node.lineno}: {name}" for name in names if name == "pchc_rsl.cli" or name.startswith("pchc_rsl.cli.")]
    return found


def library_files():
    for folder in LIBRARY:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if "cli" not in path.relative_to(ROOT).parts[1:2]:
                yield path


def test_the_import_check_sees_an_import_of_the_cli(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import os\nfrom pchc_rsl.cli.play import main\nfrom pchc_rsl import cli\n"
                      "import pchc_rsl.training.build\n")
    assert cli_imports(sample) == ["2: pchc_rsl.cli.play", "2: pchc_rsl.cli.play.main", "3: pchc_rsl.cli"]


def test_no_library_module_or_tool_imports_the_cli():
    files = list(library_files())
    assert any(p.name == "build.py" for p in files) and any(p.parent.name == "studies" for p in files)
    offenders = {str(p.relative_to(ROOT)): hits for p in files if (hits := cli_imports(p))}
    assert offenders == {}, f"library code imports the CLI (move the shared code into a library module): {offenders}"


def tool_names() -> set[str]:
    return {path.stem for path in (ROOT / "tools").rglob("*.py")}


def tools_or_path_edits(path: pathlib.Path, tools: set[str]) -> list[str]:
    """'line: what' for every import of a tool (tools/**/NAME.py imported as NAME) and every edit of sys.path in one
    file: a tool imports the package, never another tool."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [f"{node.lineno}: import {a.name}" for a in node.names if a.name.split(".")[0] in tools]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module.split(".")[0] in tools:
            found.append(f"{node.lineno}: from {node.module} import")
        elif (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute) and node.value.attr == "path"
              and isinstance(node.value.value, ast.Name) and node.value.value.id == "sys"):
            found.append(f"{node.lineno}: sys.path.{node.attr}")
    return sorted(found, key=lambda hit: int(hit.split(":")[0]))


def test_the_tool_check_sees_an_import_of_a_tool_and_a_sys_path_edit(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import os, sys\nsys.path.insert(0, os.path.dirname(__file__))\nimport mo_benchmark\n"
                      "from mo_study import Cell\nfrom pchc_rsl.evaluation import expert_usage\n")
    assert tools_or_path_edits(sample, {"mo_benchmark", "mo_study", "expert_usage"}) == [
        "2: sys.path.insert", "3: import mo_benchmark", "4: from mo_study import"]


def test_tools_import_the_package_and_never_each_other():
    tools = tool_names()
    assert {"mo_benchmark", "g1_report", "bench_env"} <= tools
    offenders = {str(p.relative_to(ROOT)): hits for p in sorted((ROOT / "tools").rglob("*.py"))
                 if (hits := tools_or_path_edits(p, tools))}
    assert offenders == {}, f"a tool imports another tool or edits sys.path (move the shared code into the package): " \
                            f"{offenders}"


def test_a_run_without_the_g1_model_ends_by_counting_its_skipped_g1_tests():
    from conftest import G1_SKIP, g1_skip_line

    assert g1_skip_line(["chromium missing", "set PCHC_MOTION_DIR"]) is None
    line = g1_skip_line([G1_SKIP, "chromium missing", G1_SKIP, G1_SKIP])
    assert line.startswith("3 of 4 skipped tests need the Unitree G1 model") and "MENAGERIE_ROOT" in line


def unit_of(path: pathlib.Path) -> str | None:
    """The entry of LAYERS a source file belongs to (None for pchc_rsl/__init__.py)."""
    parts = path.relative_to(ROOT).parts
    if parts[0] in MAPPED:
        return parts[0]
    name = parts[1].removesuffix(".py")
    return None if name == "__init__" else name


def imported_units(path: pathlib.Path) -> list[tuple[int, str]]:
    """(line, entry of LAYERS) of every import of pchc_rsl.<entry> in one file, in functions too."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module == "pchc_rsl":
            names = [f"pchc_rsl.{alias.name}" for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module is not None and node.level == 0:
            names = [node.module]
        else:
            continue
        found += [(node.lineno, name.split(".")[1]) for name in names if name.startswith("pchc_rsl.")]
    return found


def upward_imports(path: pathlib.Path, unit: str) -> list[str]:
    """'line: unit -> imported unit' for every import of a package at or above ``unit``'s layer (itself excepted)."""
    rank = LAYERS.index(unit)
    return [f"{line}: {unit} -> {other}" for line, other in sorted(imported_units(path))
            if other != unit and (other not in LAYERS or LAYERS.index(other) >= rank)]


def package_files():
    for folder in ("pchc_rsl", *MAPPED):
        yield from sorted((ROOT / folder).rglob("*.py"))


def test_the_layer_check_sees_an_import_of_a_higher_or_unknown_package(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import pchc_rsl.utils.files\nfrom pchc_rsl import preference, viewers\n"
                      "def f():\n    from pchc_rsl.training.build import make_runner\n    import pchc_rsl.misc\n"
                      "from pchc_rsl.runners import load_checkpoint\n")
    expected = ["2: runners -> viewers", "4: runners -> training", "5: runners -> misc"]
    assert upward_imports(sample, "runners") == expected
    assert upward_imports(sample, "cli") == ["5: cli -> misc"]


def test_every_package_has_its_place_in_the_layers():
    units = {unit for path in package_files() if (unit := unit_of(path)) is not None}
    assert {"export", "training", "viewers", "envs"} <= units
    assert sorted(units) == sorted(LAYERS), "place a new package in LAYERS, above everything it imports"


def test_each_package_imports_only_the_packages_beneath_it():
    offenders = {str(p.relative_to(ROOT)): hits for p in package_files()
                 if (unit := unit_of(p)) in LAYERS and (hits := upward_imports(p, unit))}
    assert offenders == {}, f"imports against the layers (move the shared code down, or the importer up): {offenders}"


def test_the_deploy_reads_a_policy_files_metadata_without_torch():
    """pchc-deploy checks its arguments against the file before torch has loaded (a second, not several); the
    simulated robot's bridge runs without torch too."""
    code = ("import sys\nfrom pchc_rsl.deploy.live_controls import check_preference, command_ranges_of\n"
            "from pchc_rsl.deploy.policy_file import read_metadata\n"
            "import pchc_rsl.cli.deploy, pchc_rsl.cli.sim_bridge\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'torch'))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


MUJOCO_GL = ("loads MuJoCo, which reads MUJOCO_GL once, when it is first imported: --video without a display chooses "
             "EGL before (test_without_a_display_video_chooses_egl_before_mujoco_loads)")
LAZY_IMPORTS = {
    "envs/physics/backend.py: pchc_rsl.envs.physics.warp_mujoco":
        "MuJoCo Warp is optional (the warp extra): the default C MuJoCo physics runs without it",
    "pchc_rsl/cli/deploy.py: pchc_rsl.deploy.deployment":
        "loads torch, and pchc-deploy first checks its arguments against the policy file's metadata, within a "
        "second (test_the_deploy_reads_a_policy_files_metadata_without_torch)",
    "pchc_rsl/cli/deploy.py: pchc_rsl.deploy.policy_step": "loads torch, as pchc_rsl.deploy.deployment does",
    "pchc_rsl/cli/deploy.py: pchc_rsl.deploy.simulator": "MuJoCo, for --mujoco only: a robot's deploy never loads it",
    "pchc_rsl/cli/export_onnx.py: pchc_rsl.training.checkpoint_export":
        "loads torch (3 s): a bad -o (a folder, a file there without --force) is refused at once",
    "pchc_rsl/cli/eval.py: pchc_rsl.cli.eval_run": MUJOCO_GL,
    "pchc_rsl/cli/play.py: pchc_rsl.cli.play_run": MUJOCO_GL,
}
"""'file: module' -> why that import of the package's own module waits inside a function. Everything else is
imported at the top of its module, so that a module names what it depends on and an import cycle cannot hide."""


def in_function_imports(path: pathlib.Path) -> list[str]:
    """'line: module' for every import of pchc_rsl or a module in it made inside a function of one file."""
    found = []
    for function in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if not isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(function):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module is not None and node.level == 0:
                names = [f"{node.module}.{alias.name}" if node.module == "pchc_rsl" else node.module
                         for alias in node.names]
            else:
                continue
            found += [f"{node.lineno}: {name}" for name in names if name.split(".")[0] == "pchc_rsl"]
    return sorted(set(found), key=lambda hit: int(hit.split(":")[0]))


def test_the_count_sees_an_import_inside_a_function(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import os\nfrom pchc_rsl.utils.files import atomic_write\n\n\ndef f():\n    import json\n"
                      "    from pchc_rsl.training.build import make_runner\n\n    def g():\n"
                      "        from pchc_rsl import preference\n        import pchc_rsl.deploy.sdk\n")
    assert in_function_imports(sample) == ["7: pchc_rsl.training.build", "10: pchc_rsl.preference",
                                           "11: pchc_rsl.deploy.sdk"]


def test_the_package_imports_its_own_modules_at_the_top_unless_listed_with_a_reason():
    found = {f"{path.relative_to(ROOT)}: {hit.split(': ')[1]}" for path in package_files()
             for hit in in_function_imports(path)}
    assert found - set(LAZY_IMPORTS) == set(), ("import these at the top of their modules (a cycle: move the shared "
                                                "code down a layer), or list them in LAZY_IMPORTS with the reason")
    assert set(LAZY_IMPORTS) - found == set(), "LAZY_IMPORTS lists imports that are gone: remove them"
    assert all(reason.strip() for reason in LAZY_IMPORTS.values())
