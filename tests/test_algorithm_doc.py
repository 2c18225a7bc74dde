"""docs/ALGORITHM.md maps Algorithm 1 to the code: every name it cites exists, and the loop it describes stays short."""

from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "ALGORITHM.md"
#: A citation: `dsage_ray.module.path:Qualified.name`.
CITATION = re.compile(r"`(dsage_ray(?:\.\w+)*):([A-Za-z_][\w.]*)`")
#: The paper's lines, in the order of its listing: each must have its row.
PSEUDOCODE = (
    "Initialize the ground-truth archive", "generate_random_solutions(n_rand)", "env ← g(θ)", "evaluate(env)",
    "D ← D ∪", "add_solution(A_gt", "evals ← n_rand", "while evals < N", "Initialize a QD optimizer qd",
    "for itr ∈", "qd.ask(B)", "sm.predict_ancillary(env)", "sm.predict(env, ŷ)", "qd.tell",
    "select_solutions(A_surrogate)",
    "evals ← evals + 1", "sm.train(D)",
)


def citations(text: str) -> list[tuple[str, str]]:
    return CITATION.findall(text)


def resolve(module: str, qualname: str) -> object:
    """The object ``module:qualname`` names (AttributeError or ImportError where there is none)."""
    target: object = importlib.import_module(module)
    for part in qualname.split("."):
        target = getattr(target, part)
    return target


def test_the_doc_cites_names():
    assert len(citations(DOC.read_text())) >= 40


@pytest.mark.parametrize("module, qualname", sorted(set(citations(DOC.read_text()))),
                         ids=lambda value: value)
def test_every_name_the_doc_cites_exists(module, qualname):
    target = resolve(module, qualname)
    assert callable(target) or isinstance(target, property), f"{module}:{qualname} is no function, class or property"


def test_a_missing_name_is_caught():
    with pytest.raises(AttributeError):
        resolve("dsage_ray.core.runner", "DSAGE.no_such_phase")
    assert citations("`dsage_ray.core.runner:DSAGE._step` and `dsage_ray.qd:x` but not `numpy:array`") == [
        ("dsage_ray.core.runner", "DSAGE._step"), ("dsage_ray.qd", "x")]


def test_every_line_of_the_pseudocode_has_a_row_with_a_citation_in_order():
    rows = [line for line in DOC.read_text().splitlines() if line.startswith("| ") and citations(line)]
    found = []
    for fragment in PSEUDOCODE:
        matching = [i for i, row in enumerate(rows) if fragment in row.split("|")[1]]
        assert matching, f"no row for the line {fragment!r}"
        found.append(matching[0])
    assert found == sorted(found), "the rows are not in the listing's order"


def test_an_outer_iteration_reads_in_forty_lines_at_most():
    from dsage_ray.core.runner import DSAGE

    lines, _ = inspect.getsourcelines(DSAGE._step)
    assert len(lines) <= 40, f"DSAGE._step is {len(lines)} lines"
