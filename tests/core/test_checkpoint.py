"""The one checkpoint format: exact round trips, atomic writes, foreign and damaged files, library versions."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import re
import warnings

import numpy as np
import pytest
import torch

from dsage_ray.core import checkpoint
from dsage_ray.core.checkpoint import (CheckpointError, CheckpointVersionError, CheckpointVersionWarning,
                                       load_checkpoint, read_header, save_checkpoint)
from dsage_ray.errors import InputError, describe
from dsage_ray.qd import make_archive


@pytest.fixture
def state():
    archive = make_archive(solution_dim=4, dims=(4, 4), ranges=[(0, 1), (0, 1)], seed=3)
    rng = np.random.default_rng(0)
    archive.add(rng.random((10, 4)), rng.random(10), rng.random((10, 2)))
    return {"archive": archive, "weights": torch.arange(6.0), "rng": rng.bit_generator.state, "evals": 10}


def saved_with(monkeypatch, path, state, **versions):
    """Saves ``state`` as if the named libraries had the given versions."""
    fake = {**checkpoint.library_versions(), **versions}
    with monkeypatch.context() as patch:
        patch.setattr(checkpoint, "library_versions", lambda: dict(fake))
        save_checkpoint(state, path)
    return path


def test_round_trip_is_exact_and_the_header_names_format_and_versions(tmp_path, state):
    path = save_checkpoint(state, tmp_path / "run" / "c.dsage")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # same versions: not a word
        loaded = load_checkpoint(path)
    assert loaded["evals"] == 10 and torch.equal(loaded["weights"], state["weights"])
    assert loaded["rng"] == state["rng"]
    for name in state["archive"].field_list:
        np.testing.assert_array_equal(loaded["archive"].data(name), state["archive"].data(name))
    header = read_header(path)
    assert header["format"] == checkpoint.FORMAT_VERSION
    assert set(header["libraries"]) == {"dsage_ray", "ribs", "numpy", "torch"}
    assert "config" not in header  # a state without a run config


def test_the_header_carries_the_runs_config_so_it_reads_without_the_state(tmp_path, state):
    config = {"domain": "maze", "seed": 7, "selection": {"elite_mutants": 0}}
    path = save_checkpoint({**state, "config": config}, tmp_path / "c.dsage")
    assert read_header(path)["config"] == config


def test_save_is_atomic_and_replaces_the_previous_file(tmp_path, state, monkeypatch):
    path = save_checkpoint(state, tmp_path / "c.dsage")
    before = path.read_bytes()

    def crash(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("os.fsync", crash)
    with pytest.raises(OSError):
        save_checkpoint({**state, "evals": 11}, path)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["c.dsage"]
    monkeypatch.undo()
    save_checkpoint({**state, "evals": 11}, path)
    assert load_checkpoint(path)["evals"] == 11


@pytest.mark.parametrize("content, needle", [
    (b"this is not a checkpoint at all\n" * 10, "not a dsage_ray checkpoint"),
    (pickle.dumps({"format": "dsage_ray.checkpoint.v1", "state": {}}), "not a dsage_ray checkpoint"),
    (b"dsage_ray checkpoint\n{no json", "header is incomplete"),
    (b"dsage_ray checkpoint\n[1, 2]\nxx", "header is not the JSON object"),
    (b'dsage_ray checkpoint\n{"format": 1}\nxx', "checkpoint format 1"),
])
def test_foreign_files_fail_with_an_input_error_naming_the_file(tmp_path, content, needle):
    path = tmp_path / "odd.dsage"
    path.write_bytes(content)
    with pytest.raises(CheckpointError, match=needle) as info:
        load_checkpoint(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    assert isinstance(info.value, InputError) and describe(info.value)[0] == 2


def test_a_torch_save_file_is_refused(tmp_path):
    path = tmp_path / "runner_state.pt"
    torch.save({"archive": None}, path)
    with pytest.raises(CheckpointError, match="not a dsage_ray checkpoint"):
        load_checkpoint(path)


def test_missing_and_folder_paths(tmp_path):
    with pytest.raises(CheckpointError, match="no such checkpoint"):
        load_checkpoint(tmp_path / "nope.dsage")
    with pytest.raises(CheckpointError, match="is a folder"):
        load_checkpoint(tmp_path)


@pytest.mark.parametrize("damage", ["truncate", "flip"])
def test_damaged_files_are_caught_by_the_checksum(tmp_path, state, damage):
    path = save_checkpoint(state, tmp_path / "c.dsage")
    data = bytearray(path.read_bytes())
    if damage == "truncate":
        data = data[: len(data) - 100]
    else:
        data[-50] ^= 0x01
    path.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="damaged checkpoint") as info:
        load_checkpoint(path)
    assert str(path) in str(info.value)


def test_another_pyribs_minor_release_is_an_error(tmp_path, state, monkeypatch):
    path = saved_with(monkeypatch, tmp_path / "c.dsage", state, ribs="0.11.0")
    with pytest.raises(CheckpointVersionError, match=r"pyribs 0\.11\.0.*install ribs==0\.11\.0") as info:
        load_checkpoint(path)
    assert str(path) in str(info.value) and describe(info.value)[0] == 2


@pytest.mark.parametrize("library", ["numpy", "torch", "dsage_ray", "ribs"])
def test_other_versions_that_load_are_a_warning(tmp_path, state, monkeypatch, library):
    running = checkpoint.library_versions()[library]
    # A different patch release for pyribs (same major.minor), any difference for the others.
    other = ".".join(running.split(".")[:2] + ["999"]) if library == "ribs" else "0.0.1"
    path = saved_with(monkeypatch, tmp_path / "c.dsage", state, **{library: other})
    with pytest.warns(CheckpointVersionWarning, match=re.escape(f"{library} {other} (now {running})")):
        loaded = load_checkpoint(path)
    assert loaded["evals"] == 10


def forged(path, payload: bytes):
    """A checkpoint file around ``payload`` with a correct header: what anyone can write (the checksum is no seal)."""
    header = {"format": checkpoint.FORMAT_VERSION, "libraries": checkpoint.library_versions(),
              "payload_bytes": len(payload), "payload_sha256": hashlib.sha256(payload).hexdigest()}
    path.write_bytes(checkpoint._MAGIC + json.dumps(header).encode() + b"\n" + payload)
    return path


class RunsCode:
    """Unpickles by calling ``function(*arguments)``: the way a forged pickle runs code."""

    def __init__(self, function, *arguments):
        self.function, self.arguments = function, arguments

    def __reduce__(self):
        return self.function, self.arguments


def code_payloads(marker):
    """Pickles that, read by a plain ``pickle.loads``, would create ``marker``."""
    import os

    write = f"open({str(marker)!r}, 'w').write('ran')"
    return {"os.system": pickle.dumps({"archive": RunsCode(os.system, f"touch {marker}")}),
            "eval": pickle.dumps({"archive": RunsCode(eval, write)}),
            "exec in a nested list": pickle.dumps({"history": [1, [RunsCode(exec, write)]]}),
            "getattr": pickle.dumps({"archive": RunsCode(getattr, np.random.default_rng(), "bit_generator")})}


@pytest.mark.parametrize("kind", ["os.system", "eval", "exec in a nested list", "getattr"])
def test_a_forged_checkpoint_runs_no_code_and_names_what_it_refused(tmp_path, kind):
    marker = tmp_path / "ran"
    payload = code_payloads(marker)[kind]
    pickle.loads(payload) if kind == "getattr" else None  # noqa: S301 - getattr is harmless here; the rest is not run
    path = forged(tmp_path / "c.dsage", payload)
    with pytest.raises(CheckpointError, match="refused: it names .*which a checkpoint may not hold") as error:
        load_checkpoint(path)
    assert not marker.exists() and str(path) in str(error.value) and describe(error.value)[0] == 2


def test_a_state_that_does_not_load_names_the_file_and_its_versions(tmp_path):
    # Allowed classes called with wrong arguments: a forger gets an error, not a state.
    path = forged(tmp_path / "c.dsage", pickle.dumps({"dtype": RunsCode(np.dtype, "no-such-dtype")}))
    with pytest.raises(CheckpointError, match=r"does not load \(TypeError.*written with dsage_ray") as info:
        load_checkpoint(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("record", [("torch.tensor", "float32", (3,), b"\0" * 8),
                                    ("torch.tensor", "complex64", (1,), b"\0" * 8),
                                    ("torch.tensor", "float32", (-1,), b""), ("os.system", "ls")])
def test_a_malformed_tensor_record_is_refused(tmp_path, record):
    import io

    class Pickler(pickle.Pickler):
        def persistent_id(self, obj):
            return record if obj == "tensor here" else None

    buffer = io.BytesIO()
    Pickler(buffer, protocol=5).dump({"weights": "tensor here"})
    with pytest.raises(CheckpointError, match="refused: .*tensor record"):
        load_checkpoint(forged(tmp_path / "c.dsage", buffer.getvalue()))


def test_tensors_round_trip_as_data_whatever_their_dtype_and_layout(tmp_path):
    tensors = {"bf16": torch.randn(3, 4).to(torch.bfloat16), "scalar": torch.tensor(2.5),
               "transposed": torch.arange(12.0).reshape(3, 4).T, "empty": torch.zeros(0, 5),
               "bool": torch.tensor([True, False]), "parameter": torch.nn.Parameter(torch.ones(2)),
               "long": torch.arange(5)}
    loaded = load_checkpoint(save_checkpoint({"tensors": tensors}, tmp_path / "c.dsage"))["tensors"]
    for name, tensor in tensors.items():
        assert loaded[name].dtype == tensor.dtype and torch.equal(loaded[name], tensor.detach()), name


def test_a_state_the_reader_would_refuse_fails_when_saved_not_when_resumed(tmp_path):
    with pytest.raises(TypeError, match="cannot save a checkpoint .*names posix.getcwd"):
        save_checkpoint({"thing": RunsCode(os.getcwd)}, tmp_path / "c.dsage")
    assert not (tmp_path / "c.dsage").exists()


def test_a_checkpoint_without_a_run_config_is_named_not_a_key_error(tmp_path, state):
    from dsage_ray.core.checkpoint import checkpoint_config

    path = save_checkpoint(state, tmp_path / "c.dsage")  # a valid checkpoint, but of no run
    with pytest.raises(CheckpointError, match="holds no run config") as error:
        checkpoint_config(path)
    assert describe(error.value)[0] == 2 and "\n" not in str(error.value)
