"""A failed write leaves the user's existing file as it was, and no temporary file behind."""

import pytest

from efam_mujoco.files import OutputError, check_outputs, write_json_atomic, write_text_atomic


def test_failed_write_keeps_the_old_file(tmp_path):
    path = write_text_atomic(tmp_path / "out.json", '{"kept": true}\n')
    with pytest.raises(TypeError):
        write_json_atomic(path, {"bad": object()})  # not serialisable: fails before any write
    assert path.read_text() == '{"kept": true}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_write_creates_folders(tmp_path):
    path = write_json_atomic(tmp_path / "a" / "b.json", {"x": 1})
    assert path.read_text() == '{\n "x": 1\n}\n'


def test_an_unwritable_place_is_named_as_the_user_wrote_it(tmp_path):
    # a folder that cannot be made (a file stands where it would go): the error names the
    # user's path, not the temporary file beside it that nobody asked for
    (tmp_path / "taken").write_text("a file")
    with pytest.raises(OutputError, match=r"cannot write .*taken/out\.json") as caught:
        write_json_atomic(tmp_path / "taken" / "out.json", {"x": 1})
    assert "efam-tmp" not in str(caught.value)


def test_a_json_output_that_is_a_folder_is_refused_before_any_work(tmp_path):
    with pytest.raises(OutputError, match=r"--json .*: is a folder, not a file; give a file name"):
        check_outputs({"--json": tmp_path}, {})
