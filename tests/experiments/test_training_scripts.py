"""The training scripts' command lines (``experiments/train_*.py``): typed ``Args`` dataclasses parsed by tyro.

Every field must carry a docstring, ``--help`` must show each flag with it, and every boolean must be
switchable both ways (``--x`` / ``--no-x``), whatever its default.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted((REPO_ROOT / "experiments").glob("train_*.py"))


def field_docs(script: Path) -> dict[str, str | None]:
    """``{field: docstring or None}`` for the ``Args`` dataclass, read from the source (a string right after a field)."""
    tree = ast.parse(script.read_text())
    (args,) = [node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == "Args"]
    docs: dict[str, str | None] = {}
    for node, following in zip(args.body, [*args.body[1:], None]):
        if isinstance(node, ast.AnnAssign):
            is_doc = (isinstance(following, ast.Expr) and isinstance(following.value, ast.Constant)
                      and isinstance(following.value.value, str))
            docs[node.target.id] = following.value.value if is_doc else None
    return docs


@pytest.fixture
def load(monkeypatch):
    """Imports a script by path; it stays in ``sys.modules`` for the test (tyro resolves annotations there)."""
    def load_script(script: Path):
        spec = importlib.util.spec_from_file_location(script.stem, script)
        module = importlib.util.module_from_spec(spec)
        monkeypatch.setitem(sys.modules, spec.name, module)
        spec.loader.exec_module(module)
        return module

    return load_script


def flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def squash(text: str) -> str:
    """Help text without rich's box drawing and line wrapping."""
    return " ".join(re.sub(r"[│╭╮╰╯─]", " ", text).split())


def test_there_are_training_scripts():
    assert {s.name for s in SCRIPTS} >= {"train_maze_agent.py", "train_mario_gan.py"}


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda s: s.name)
def test_help_lists_every_flag_with_its_description(script):
    docs = field_docs(script)
    assert docs, f"{script.name}: no Args dataclass"
    undocumented = [name for name, doc in docs.items() if not doc]
    assert not undocumented, f"{script.name}: fields without a docstring (help text): {undocumented}"
    env = dict(os.environ, COLUMNS="200", PYTHONPATH=str(REPO_ROOT))
    done = subprocess.run([sys.executable, str(script), "--help"], env=env, capture_output=True, text=True,
                          timeout=120, cwd=REPO_ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    shown = squash(done.stdout)
    for name, doc in docs.items():
        assert flag(name) in shown, f"{script.name}: {flag(name)} missing from --help"
        assert squash(doc) in shown, f"{script.name}: help text of {flag(name)} missing from --help"


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda s: s.name)
def test_every_boolean_switches_both_ways(script, load):
    module = load(script)
    booleans = [f.name for f in dataclasses.fields(module.Args) if f.type in (bool, "bool")]
    for name in booleans:
        assert getattr(module.parse_args([flag(name)]), name) is True
        no = "--no-" + flag(name)[2:]
        assert getattr(module.parse_args([no]), name) is False


def test_maze_script_has_a_boolean_on_by_default_and_typed_values(load):
    module = load(REPO_ROOT / "experiments" / "train_maze_agent.py")
    assert module.Args().see_through_walls is True
    args = module.parse_args(["--no-see-through-walls", "--lr", "0.001", "--num-envs", "3"])
    assert (args.see_through_walls, args.lr, args.num_envs) == (False, 0.001, 3)


def test_gan_script_fills_in_the_learning_rate_of_its_loss(load):
    module = load(REPO_ROOT / "experiments" / "train_mario_gan.py")
    assert module.parse_args([]).lr == 1e-4
    assert module.parse_args(["--loss", "clip"]).lr == 5e-5
    assert module.parse_args(["--loss", "clip", "--lr", "0.01"]).lr == 0.01


def test_bad_values_are_rejected_before_anything_runs(load):
    module = load(REPO_ROOT / "experiments" / "train_mario_gan.py")
    with pytest.raises(SystemExit) as info:
        module.parse_args(["--loss", "nope"])
    assert info.value.code == 2
