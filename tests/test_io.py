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


def _hold_lock(folder, ready):
    """A child process that takes the folder's lock and waits to be killed."""
    import time

    with io.folder_lock(folder, what="audit"):
        ready.set()
        time.sleep(60)


@pytest.mark.skipif(os.name != "posix", reason="flock")
def test_a_second_writer_of_a_folder_is_refused_until_the_first_one_dies_however_it_dies(tmp_path):
    import multiprocessing

    from dsage_ray.errors import InputError

    context = multiprocessing.get_context("spawn")
    ready = context.Event()
    holder = context.Process(target=_hold_lock, args=(tmp_path / "audit", ready))
    holder.start()
    try:
        assert ready.wait(60)
        with pytest.raises(InputError, match=rf"another audit is writing this folder \(process {holder.pid}\)"):
            with io.folder_lock(tmp_path / "audit", what="audit"):
                pass
    finally:
        holder.kill()  # SIGKILL: no cleanup code runs, and no stale lock may stay
        holder.join()
    with io.folder_lock(tmp_path / "audit", what="audit"):
        assert (tmp_path / "audit" / io.LOCK_NAME).read_text() == f"{os.getpid()}\n"


def test_a_folder_that_cannot_be_written_is_named_before_any_work(tmp_path):
    from dsage_ray.errors import InputError

    (tmp_path / "a_file").write_text("")
    with pytest.raises(InputError, match=r"a_file/out: cannot write the run's output there \(Not a directory\)"):
        with io.folder_lock(tmp_path / "a_file" / "out", what="run"):
            pytest.fail("entered")


def test_what_a_killed_writer_left_is_cleared_and_its_old_contents_put_back(tmp_path):
    final = tmp_path / "collection"
    io.staging_dir(final)  # a writer killed while writing
    old = tmp_path / ".collection.old"
    old.mkdir()  # ... and one killed between replace_dir's two renames (where there is no exchange)
    (old / "collection.json").write_text("{}")
    io.recover_replaced_dir(final)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["collection"]
    assert (final / "collection.json").read_text() == "{}"


def test_replace_dir_swaps_in_one_step_where_the_system_can(tmp_path):
    final = tmp_path / "collection"
    final.mkdir()
    (final / "v").write_text("old")
    staging = io.staging_dir(final)
    (staging / "v").write_text("new")
    exchanges = []
    original = io._exchange
    io._exchange = lambda a, b: exchanges.append((a, b)) or original(a, b)
    try:
        io.replace_dir(staging, final)
    finally:
        io._exchange = original
    assert (final / "v").read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["collection"]
    if io._renameat2() is not None:
        assert exchanges == [(staging, final)]
