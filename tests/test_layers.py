"""The command-line interfaces are the edge: library code (pchc_rsl, envs, robots, configs) and the tools never import
pchc_rsl.cli, so everything a CLI does can be called from Python without parsing arguments."""

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
LIBRARY = ["pchc_rsl", "envs", "robots", "configs", "tools", "examples"]


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
    assert any(p.name == "build.py" for p in files) and any(p.parent.name == "tools" for p in files)
    offenders = {str(p.relative_to(ROOT)): hits for p in files if (hits := cli_imports(p))}
    assert offenders == {}, f"library code imports the CLI (move the shared code into a library module): {offenders}"


def test_a_run_without_the_g1_model_ends_by_counting_its_skipped_g1_tests():
    from conftest import G1_SKIP, g1_skip_line

    assert g1_skip_line(["chromium missing", "set PCHC_MOTION_DIR"]) is None
    line = g1_skip_line([G1_SKIP, "chromium missing", G1_SKIP, G1_SKIP])
    assert line.startswith("3 of 4 skipped tests need the Unitree G1 model") and "MENAGERIE_ROOT" in line
