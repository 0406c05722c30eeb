"""Files a person keeps are written whole: write_json leaves the JSON and nothing else."""

import json

from pchc_rsl.utils.files import write_json


def test_write_json_replaces_the_file_with_indented_json_and_leaves_no_temporary_file(tmp_path):
    path = tmp_path / "progress.json"
    path.write_text("old")
    data = {"done": 3, "history": [{"env_steps": 2048, "hypervolume": 1.5}], "resumed": 0}
    assert write_json(str(path), data) == str(path)
    assert path.read_text() == json.dumps(data, indent=2)
    assert [p.name for p in tmp_path.iterdir()] == ["progress.json"]
