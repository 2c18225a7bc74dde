"""A forged audit folder runs no code on any command that reads its checkpoint (issue 46's probes, as commands)."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
from pathlib import Path

import pytest

from dsage_ray.audit.collection import audit_config
from dsage_ray.cli import main
from dsage_ray.core import checkpoint

AUDIT = ["audit", "--domain", "gym", "--space", "cartpole", "--agent", "random", "--preset", "tiny", "--local"]


class Touch:
    """Unpickled by plain pickle as ``os.system("touch MARKER")``."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


@pytest.fixture
def forged_audit(tmp_path):
    """An audit folder as someone else could send it: a valid header (the run's config, a correct checksum) over a
    state whose every part would run ``touch`` when unpickled; yields ``(folder, marker)``."""
    folder, marker = tmp_path / "forged", tmp_path / "code-ran"
    config = audit_config(domain="gym", agent="random", preset="tiny", overrides={"gym.space": "cartpole"}).to_dict()
    state = {"config": config, "evals": 40, "archive": Touch(marker), "surrogate": Touch(marker),
             "dataset": Touch(marker)}
    payload = pickle.dumps(state)
    header = {"format": checkpoint.FORMAT_VERSION, "libraries": checkpoint.library_versions(), "config": config,
              "payload_bytes": len(payload), "payload_sha256": hashlib.sha256(payload).hexdigest()}
    (folder / "search").mkdir(parents=True)
    (folder / "search" / checkpoint.CHECKPOINT_NAME).write_bytes(
        checkpoint._MAGIC + json.dumps(header).encode() + b"\n" + payload)
    yield folder, marker
    assert not marker.exists(), "the forged checkpoint ran code"


@pytest.mark.parametrize("command", [
    ["surrogate", "info", "{folder}"],
    ["surrogate", "pretrain", "--from", "{folder}", "--out", "{tmp}/pretrained.dsage"],
    [*AUDIT, "--out", "{tmp}/new", "--surrogate-init", "{folder}"],
    [*AUDIT, "--out", "{folder}", "--collect-only"],
    [*AUDIT, "--out", "{folder}", "--resume"],
], ids=["surrogate info", "surrogate pretrain --from", "--surrogate-init", "--collect-only", "--resume"])
def test_a_forged_audit_folder_is_refused_by_every_command_that_reads_it(forged_audit, tmp_path, command, capsys):
    folder, _ = forged_audit
    argv = [part.format(folder=folder, tmp=tmp_path) for part in command]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "refused: it names posix.system" in error and error.count("\n") == 1


def test_a_forged_checkpoint_read_from_python_is_refused(forged_audit):
    from dsage_ray.core.warm_start import load_warm_start
    from dsage_ray.results import RunResult

    folder, _ = forged_audit
    file = folder / "search" / checkpoint.CHECKPOINT_NAME
    with pytest.raises(checkpoint.CheckpointError, match="refused"):
        _ = RunResult(config=checkpoint.checkpoint_config(file), path=folder, checkpoint=file).archive
    with pytest.raises(Exception, match="refused"):  # audit-series warm-starts through this
        load_warm_start(folder)
