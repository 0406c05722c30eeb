"""Results record a checkpoint relative to the working directory when it lies under it, so that a results folder
committed beside the policy it measures names it the same way in every checkout."""

import os

from pchc_rsl.utils.files import recorded_path


def test_under_the_working_directory_the_path_is_relative(tmp_path, monkeypatch):
    (tmp_path / "policies").mkdir()
    monkeypatch.chdir(tmp_path)
    assert recorded_path("policies/g1_walk.pt") == os.path.join("policies", "g1_walk.pt")
    assert recorded_path(str(tmp_path / "policies" / "g1_walk.pt")) == os.path.join("policies", "g1_walk.pt")
    assert recorded_path("./policies/../policies/g1_walk.pt") == os.path.join("policies", "g1_walk.pt")


def test_outside_it_the_path_is_absolute(tmp_path, monkeypatch):
    (tmp_path / "repo").mkdir()
    monkeypatch.chdir(tmp_path / "repo")
    assert recorded_path("../runs/model_10.pt") == str(tmp_path / "runs" / "model_10.pt")
    assert recorded_path("..") == str(tmp_path)
    assert recorded_path("..runs/model_10.pt") == os.path.join("..runs", "model_10.pt")  # a folder named '..runs'
