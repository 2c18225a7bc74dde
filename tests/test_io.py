import os
import stat

import pytest

from dsage_ray import io


def test_atomic_write_replaces_whole_file_with_plain_open_permissions(tmp_path):
    target = tmp_path / "out.json"
    io.atomic_write_json(target, {"a": 1})
    io.atomic_write_json(target, {"b": 2})
    assert target.read_text() == '{\n  "b": 2\n}\n'
    reference = tmp_path / "reference"
    reference.write_text("x")  # what open() gives under this process's umask
    assert stat.S_IMODE(os.stat(target).st_mode) == stat.S_IMODE(os.stat(reference).st_mode)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_atomic_write_failure_leaves_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "out.json"
    io.atomic_write_json(target, {"a": 1})
    with pytest.raises(TypeError):
        io.atomic_write_json(target, {"a": object()})
    assert target.read_text() == '{\n  "a": 1\n}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_staging_dir_swapped_in_has_plain_mkdir_permissions(tmp_path):
    final = tmp_path / "elites"
    for content in ("old", "new"):
        staging = io.staging_dir(final)
        assert staging.parent == tmp_path and staging != final and not any(staging.iterdir())
        (staging / "a.txt").write_text(content)
        io.replace_dir(staging, final)
    assert (final / "a.txt").read_text() == "new"
    reference = tmp_path / "reference"
    reference.mkdir()  # what mkdir gives under this process's umask
    assert stat.S_IMODE(os.stat(final).st_mode) == stat.S_IMODE(os.stat(reference).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["elites", "reference"]
