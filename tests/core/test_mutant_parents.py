"""``experimental.mutant_parents = "evaluated"``: the elite mutants' parents among every level the run evaluated."""

import numpy as np
import pytest

from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.core.checkpoint import load_checkpoint, save_checkpoint
from dsage_ray.core.runner import DSAGE
from tests.core.test_runner import archive_snapshot, make_runner
from tests.fakes import SMALL_RUN, BitmapDomain

EVALUATED = {"selection.elite_mutants": 10, "experimental.mutant_parents": "evaluated"}


def test_the_run_keeps_every_level_it_evaluated_only_where_the_parents_are_drawn_from_them():
    runner = make_runner(**EVALUATED)
    runner.run()
    # The surrogate's dataset keeps them (and a checkpoint with it).
    solutions, objective = runner.dataset.solutions, runner.dataset.objective
    assert len(solutions) == len(objective) == runner.evals == SMALL_RUN["budget"]
    # The archive's elites are among them, with the objective they were evaluated with.
    data = runner.archive.data()
    kept = {bytes(s): o for s, o in zip(solutions.astype(np.int8), objective)}
    assert all(kept[bytes(s)] == o for s, o in zip(data["solution"].astype(np.int8), data["objective"]))
    assert make_runner(**{"selection.elite_mutants": 10}).dataset.solutions is None
    assert make_runner(**{"experimental.mutant_parents": "evaluated"}).dataset.solutions is None  # no mutants


def test_the_parents_change_the_search_and_a_resume_from_a_checkpoint_file_finds_the_same_archive(tmp_path):
    reference = make_runner(**EVALUATED)
    reference.run()
    elites = make_runner(**{"selection.elite_mutants": 10})
    elites.run()
    assert archive_snapshot(elites.archive) != archive_snapshot(reference.archive)

    interrupted = make_runner(**EVALUATED)
    interrupted.step()
    interrupted.step()
    path = save_checkpoint(interrupted.state_dict(), tmp_path / "run.dsage")
    resumed = DSAGE(config=RunConfig.build({**SMALL_RUN, **EVALUATED}), domain=BitmapDomain())
    resumed.load_state_dict(load_checkpoint(path))
    assert len(resumed.dataset.solutions) == interrupted.evals
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)


def test_a_warm_start_with_its_prior_levels_is_refused_in_one_line():
    with pytest.raises(ConfigError, match=r"experimental.mutant_parents.*init_prior = false"):
        RunConfig.build({**SMALL_RUN, **EVALUATED, "surrogate.init": "run.dsage"})
    config = RunConfig.build({**SMALL_RUN, **EVALUATED, "surrogate.init": "run.dsage",
                              "experimental.init_prior": False})
    assert config.experimental.mutant_parents == "evaluated"
