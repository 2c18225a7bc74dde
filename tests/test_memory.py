"""An evaluation that cannot fit in memory stops with one line naming the key to lower."""

from __future__ import annotations

import pytest

from dsage_ray import memory
from dsage_ray.errors import ResourceError, describe


def test_available_memory_is_read_on_this_machine():
    available = memory.available_bytes()
    assert available is None or available > 10**6


@pytest.mark.parametrize("nbytes, text", [(999, "999 B"), (1500, "1.5 KB"), (24.1e9, "24.1 GB"), (3.3e16, "33000.0 TB")])
def test_sizes_read_as_people_write_them(nbytes, text):
    assert memory.format_bytes(nbytes) == text


def test_a_request_beyond_the_available_memory_names_the_key(monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: 2 * 10**9)
    memory.require_memory(10**9, what="x", key="k")  # fits: nothing
    with pytest.raises(ResourceError) as error:
        memory.require_memory(3 * 10**9, what="1,000 episodes", key="maze.episodes (--episodes)")
    assert describe(error.value) == (3, "1,000 episodes need about 3.0 GB of memory, and 2.0 GB is available: "
                                        "lower maze.episodes (--episodes)")


def test_an_absurd_episode_count_fails_before_the_search_in_every_batched_domain(tmp_path, capsys):
    from dsage_ray.cli import main

    for domain_args in (["--agent", "builtin:random"], ["--domain", "gym", "--space", "cartpole", "--agent", "random"]):
        assert main(["audit", *domain_args, "--preset", "tiny", "--local", "--episodes", "1000000000",
                     "--out", str(tmp_path / "a")]) == 3
        error = capsys.readouterr().err
        assert "1,000,000,000 episodes side by side" in error and "episodes (--episodes)" in error
        assert not (tmp_path / "a").exists()
