"""A failed write leaves the user's existing file as it was, and no temporary file behind."""

import pytest

from efam_mujoco.files import write_json_atomic, write_text_atomic


def test_failed_write_keeps_the_old_file(tmp_path):
    path = write_text_atomic(tmp_path / "out.json", '{"kept": true}\n')
    with pytest.raises(TypeError):
        write_json_atomic(path, {"bad": object()})  # not serialisable: fails before any write
    assert path.read_text() == '{"kept": true}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_write_creates_folders(tmp_path):
    path = write_json_atomic(tmp_path / "a" / "b.json", {"x": 1})
    assert path.read_text() == '{\n "x": 1\n}\n'
