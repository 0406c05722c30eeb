"""pchc-runs: its commands' help, and bad arguments refused in one line that names the setting."""

import pytest

from pchc_rsl.cli import runs as runs_cli


def test_help_lists_the_commands_and_each_command_has_its_own(capsys):
    with pytest.raises(SystemExit) as exit_:
        runs_cli.main(["--help"])
    assert exit_.value.code == 0
    text = capsys.readouterr().out
    assert all(f"    {command}" in text for command in ("average", "curves", "release"))
    for command in ("average", "curves", "release"):
        with pytest.raises(SystemExit) as exit_:
            runs_cli.main([command, "--help"])
        assert exit_.value.code == 0
        assert capsys.readouterr().out.startswith(f"usage: pchc-runs {command} ")


@pytest.mark.parametrize("argv, named", [
    ([], "COMMAND"),
    (["plot", "RUN"], "invalid choice: 'plot'"),
    (["average", "a.pt", "b.pt"], "--out"),
    (["average", "a.pt", "b.pt", "--out", "x.pt", "--weights", "one"], "--weights"),
    (["curves", "RUN", "--smooth", "0"], "--smooth"),
    (["release", "a.pt"], "--name"),
    (["release", "a.pt", "--name", "x", "--max-mb", "0"], "--max-mb"),
])
def test_a_bad_argument_is_one_line_naming_it(argv, named, capsys):
    with pytest.raises(SystemExit) as exit_:
        runs_cli.main(argv)
    assert exit_.value.code == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith("pchc-runs") and named in error, error


def test_a_missing_checkpoint_is_one_line_naming_the_file(tmp_path):
    missing = str(tmp_path / "model_9.pt")
    with pytest.raises(SystemExit, match=f"^pchc-runs release: No checkpoint at {missing}.$"):
        runs_cli.main(["release", missing, "--name", "x", "--out", str(tmp_path / "policies")])
    with pytest.raises(SystemExit, match=f"^pchc-runs average: No checkpoint at {missing}.$"):
        runs_cli.main(["average", missing, missing, "--out", str(tmp_path / "avg.pt")])
    assert sorted(p.name for p in tmp_path.iterdir()) == []
