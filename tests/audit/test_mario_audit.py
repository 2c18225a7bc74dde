"""A tiny Mario audit in this process: levels that ``dsage-ray mario eval`` replays to the recorded numbers."""

from __future__ import annotations

import json
import shlex

import pytest

from dsage_ray.audit.collection_file import load_collection
from dsage_ray.cli import main
from dsage_ray.domains.mario.tiles import load_level
from tests.domains.mario.conftest import needs_java, needs_javac

pytestmark = [needs_java, needs_javac, pytest.mark.mario]


def test_tiny_mario_audit(tmp_path, capsys):
    out = tmp_path / "audit"
    # One outer iteration of 6 random latents, 1 run each (the tiny preset): short, and every step is real.
    assert main(["audit", "--domain", "mario", "--agent", "astar:400", "--preset", "tiny", "--budget", "6",
                 "--seed", "2", "--local", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    collection = out / "collection"
    c = load_collection(collection)
    assert (c["format"], c["domain"], c["agent"], c["reference"]) == ("dsage_ray.collection.v2", "mario",
                                                                      "astar:400", None)
    assert c["objective"] == "incompletion" and c["measures"] == ["sky_tiles", "mean_jumps"]
    levels = c["levels"]
    assert levels and len(levels) == c["search_elites"] - c["failed_reevaluations"]
    assert [lv["objective"] for lv in levels] == sorted((lv["objective"] for lv in levels), reverse=True)
    assert f"collection: {collection}" in printed and f"{len(levels)} levels:" in printed

    for lv in levels:
        assert lv["objective"] == pytest.approx(1 - lv["completion"])
        assert lv["success_rate"] == sum(s == "WIN" for s in lv["status"]) / len(lv["status"]) and lv["episodes"] == 1
        assert load_level(collection / lv["level_file"]).shape == (16, 56)
        assert (collection / lv["image_file"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    # The worst level's own command replays it to the same numbers.
    worst = levels[0]
    command = shlex.split(worst["reproduce"])
    assert command[:3] == ["dsage-ray", "mario", "eval"] and "--astar-iterations" in command
    assert main(command[1:] + ["--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["objective"] == pytest.approx(worst["completion"])
    assert again["success_rate"] == worst["success_rate"]
    assert again["mean_jumps"] == worst["jumps"] == worst["measures"]["mean_jumps"]
    assert again["sky_tiles"] == worst["sky_tiles"] == worst["measures"]["sky_tiles"]

    # compare: two A* budgets on the collection's levels (each entry's latent, checked against its level file).
    from dsage_ray.audit.compare import compare_agents

    html = tmp_path / "compare.html"
    comparison = compare_agents("astar:400", "astar:40", collection_dir=collection, html_path=html)
    assert [c["key"] for c in comparison["columns"]] == ["completion"]
    recorded = {lv["id"]: lv for lv in levels}
    assert sorted(row["id"] for row in comparison["levels"]) == sorted(recorded)
    for row in comparison["levels"]:  # A is the audited agent: its numbers are the collection's
        assert row["success_a"] == recorded[row["id"]]["success_rate"]
        assert row["completion_a"] == pytest.approx(recorded[row["id"]]["completion"])
    assert "completion A" in html.read_text()
    # Refused before any level is played: an agent Mario does not play, a level file that is not its latent's.
    assert main(["compare", "--agent", "astar", "--agent", "dcd:accel", "--collection", str(collection)]) == 2
    assert "domain 'mario' does not play 'dcd' agents" in capsys.readouterr().err
    edited = (collection / worst["level_file"]).read_text()
    (collection / worst["level_file"]).write_text(("X" if edited[0] != "X" else "-") + edited[1:])
    with pytest.raises(ValueError, match="not the level the recorded latent decodes to"):
        compare_agents("astar:400", "astar:40", collection_dir=collection)
