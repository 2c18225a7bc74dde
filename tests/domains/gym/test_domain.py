"""The gym domain: episodes on a re-parameterised environment, its checks before a search, and a whole audit."""

import json
import textwrap

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain
from dsage_ray.domains.gym.simulator import make_env, reset_env, run_episodes
from dsage_ray.domains.gym.space import SpaceError, build_space, read_space_tables
from dsage_ray.errors import InputError

#: Pushes the cart the way the pole leans: balances the default CartPole for a while, not a heavy long pole.
POLICY = '''
import numpy as np

def act(observation):
    return int(observation[2] + 0.5 * observation[3] > 0)
'''


@pytest.fixture
def policy_file(tmp_path):
    path = tmp_path / "lean.py"
    path.write_text(POLICY)
    return f"python:{path}:act"


def config(**keys):
    return RunConfig.build({"domain": "gym", "preset": "tiny", "gym.agent": "random", **keys})


def test_attributes_derived_values_and_the_first_observation_follow_the_level():
    tables, source = read_space_tables("cartpole")
    space = build_space(tables, source=source)
    values = space.values(np.array([1.0, 1.0, -1.0, 0.0, 1.0]))
    env = make_env(space, values)
    observation = reset_env(env, space, values, seed=3)
    unwrapped = env.unwrapped
    assert unwrapped.length == pytest.approx(2.0) and unwrapped.masspole == pytest.approx(0.5)
    assert unwrapped.polemass_length == pytest.approx(1.0) and unwrapped.total_mass == pytest.approx(1.0)
    # The initial angle is written into the state, and the agent's first observation says so.
    assert observation[2] == pytest.approx(0.15) and unwrapped.state[2] == pytest.approx(0.15)


def test_episodes_are_deterministic_for_a_seed_and_differ_between_seeds(policy_file):
    domain = build_domain(config(**{"gym.agent": policy_file, "gym.episodes": 4, "gym.measures": ("x_end", "length")}))
    solution = np.zeros(domain.solution_dim, dtype=np.float32)
    first, again, other = (domain.evaluate(solution, seed) for seed in (5, 5, 6))
    assert first.info == again.info and np.array_equal(first.measures, again.measures)
    assert not np.array_equal(first.measures, other.measures)  # where the cart ends up
    assert first.occupancy.shape == (8, 8) and first.occupancy.sum() == pytest.approx(first.info["mean_length"] / 500)
    assert first.objective == pytest.approx(1.0 - first.info["success_rate"])


def test_physics_changes_what_the_agent_achieves(policy_file):
    domain = build_domain(config(**{"gym.agent": policy_file, "gym.episodes": 5}))
    easy = domain.space.solution({"length": 0.5, "masspole": 0.1, "masscart": 1.0, "force_mag": 10.0,
                                  "initial_angle": 0.0})
    hard = domain.space.solution({"length": 0.25, "masspole": 0.5, "masscart": 0.5, "force_mag": 20.0,
                                  "initial_angle": 0.15})
    assert domain.evaluate(easy, 0).info["mean_length"] > 2 * domain.evaluate(hard, 0).info["mean_length"]


def test_a_level_file_reproduces_the_evaluation(policy_file, tmp_path):
    from dsage_ray.domains.gym.domain import read_level

    domain = build_domain(config(**{"gym.agent": policy_file}))
    solution = np.array([0.3, -0.2, 0.5, 0.1, -0.4], dtype=np.float32)
    path = tmp_path / "level.txt"
    path.write_text(domain.level_text(solution))
    space, values = read_level(path)
    assert values == pytest.approx(domain.values(solution))
    np.testing.assert_allclose(domain.entry_solution({"level_file": "level.txt"}, tmp_path), solution, atol=1e-6)
    path.write_text(json.dumps({"format": "other"}))
    with pytest.raises(SpaceError, match="not a gym level"):
        read_level(path)


def test_parameter_measures_are_exact_for_the_surrogate():
    domain = build_domain(config(**{"gym.measures": ("param.length", "length")}))
    solutions = np.array([[-1, 0, 0, 0, 0], [1, 0, 0, 0, 0]], dtype=np.float32)
    exact = domain.level_values(domain.encode(solutions))
    assert set(exact) == {"param.length"}
    np.testing.assert_allclose(exact["param.length"], [0.25, 2.0])


@pytest.mark.parametrize("keys, message", [
    ({"gym.env": "CartPol-v1"}, "Did you mean: `CartPole`?"),
    ({"gym.params": ("bogus=0:1",)}, "does not take these gym.make keywords ['bogus']"),
    ({"gym.params": ("attr.bogus=0:1",)}, "has no attribute 'bogus' to set"),
    ({"gym.env_args": ("enable_wind=true",)}, "['enable_wind']"),
])
def test_preflight_names_what_the_environment_does_not_take(keys, message):
    with pytest.raises(InputError) as error:
        build_domain(config(**keys)).preflight()
    assert message in str(error.value)


def test_preflight_names_a_measure_key_absent_from_info(tmp_path):
    space = tmp_path / "space.toml"
    space.write_text(textwrap.dedent("""
        [env]
        id = "CartPole-v1"
        [params.length]
        range = [0.25, 2.0]
        attr = "length"
        [measures.speed]
        info = "speed"
        range = [0, 1]
        [success]
        return_at_least = 475
    """))
    domain = build_domain(config(**{"gym.space": str(space), "gym.measures": ("speed", "param.length")}))
    with pytest.raises(SpaceError, match=r"info\['speed'\] at the end is not there"):
        domain.preflight()


def test_an_agent_for_another_environment_is_refused_before_the_search(tmp_path):
    lander = tmp_path / "lander.py"
    lander.write_text("def act(observation):\n    return 3  # LunarLander's main engine\n")
    domain = build_domain(config(**{"gym.agent": f"python:{lander}:act"}))
    with pytest.raises(InputError, match=r"not in the action space Discrete\(2\)"):
        domain.preflight()


def test_an_audit_ends_with_a_collection_a_report_and_reproducible_entries(policy_file, tmp_path, capsys):
    from dsage_ray.audit.run import run_audit
    from dsage_ray.cli import main

    # One random iteration (the budget is the tiny preset's n_rand): the search's levels are all this reads.
    collection = run_audit(domain="gym", agent=policy_file, preset="tiny", budget=20, local=True,
                           out=tmp_path / "audit", overrides={"gym.episodes": 3})
    assert collection.levels and collection.report_path.is_file()
    assert (tmp_path / "audit" / "collection" / "heatmap.png").is_file()
    worst = collection.levels[0]
    assert worst.image_path.is_file() and worst.level_path.is_file()
    record = json.loads((tmp_path / "audit" / "collection" / "collection.json").read_text())["levels"][0]
    assert record["reproduce"].startswith("dsage-ray gym eval") and "param.length" in record
    assert main(record["reproduce"].split()[1:] + ["--json"]) == 0
    printed = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert printed["mean_return"] == pytest.approx(record["mean_return"])
    assert printed["failure_rate"] == pytest.approx(record["objective"])


def test_an_evaluation_counts_the_environment_steps_it_took(policy_file):
    run = config(**{"gym.agent": policy_file})
    domain = build_domain(run)
    result = domain.evaluate(np.zeros(domain.solution_dim, dtype=np.float32), 0)
    assert domain.work_counts(result) == {"steps": result.info["mean_length"] * run.gym.episodes}


def test_a_choice_parameter_measures_as_its_index_in_episodes_and_for_the_surrogate():
    domain = build_domain(config(**{"gym.params": ("reset.mode=calm|gusty|storm",),
                                    "gym.measures": ("param.mode", "length")}))
    solution = domain.space.solution({"length": 0.5, "masspole": 0.1, "masscart": 1.0, "force_mag": 10.0,
                                      "initial_angle": 0.0, "mode": "storm"})
    assert domain.evaluate(solution, 0).measures[0] == 2.0
    assert domain.level_values(domain.encode(solution[None]))["param.mode"].tolist() == [2.0]



@pytest.mark.parametrize("measures, known", [(("param.length", "param.force_mag"), True),
                                             (("param.length", "length"), False)])
def test_with_parameter_measures_dsage_picks_only_elites_that_would_enter_the_archive(measures, known):
    """A level's cell is known before it is played when every measure is a parameter: a pick in a cell the archive
    already holds at that failure rate would be an evaluation that cannot add."""
    from dsage_ray.core.proposers import SurrogateAssisted, domain_archive
    from dsage_ray.core.seeds import RunSeeds
    from dsage_ray.qd.selection import adds_to

    run = config(**{"gym.measures": measures})
    domain = build_domain(run)
    archive = domain_archive(domain, with_occupancy=False, seed=0)
    proposer = SurrogateAssisted(config=run, domain=domain, archive=archive, seeds=RunSeeds(seed=0), evaluator=None)
    assert proposer.cells_known is known
    rng = np.random.default_rng(0)
    played = domain.random_solutions(100, rng)
    archive.add(played, np.full(100, 0.5), proposer.surrogate.predict(domain.encode(played)).measures)
    surrogate_archive = domain_archive(domain, with_occupancy=False, seed=1)
    candidates = domain.random_solutions(300, rng)
    surrogate_archive.add(candidates, rng.random(300), proposer.surrogate.predict(domain.encode(candidates)).measures)

    metrics = {}
    among, gain = proposer._picks_that_add(surrogate_archive, metrics)
    if not known:
        assert among is None and gain is None and not metrics
        return
    elites = surrogate_archive.data()
    adding = adds_to(archive, elites["objective"], elites["measures"])
    assert 0 < adding.sum() < len(adding) and metrics["selection_elites_that_add"] == adding.sum()
    np.testing.assert_array_equal(np.sort(among), np.sort(elites["index"][adding]))
    occupied, held = archive.retrieve(elites["measures"][adding])
    np.testing.assert_allclose(gain, elites["objective"][adding] - np.where(occupied, held["objective"], 0.0))
    picks, _ = proposer._select(surrogate_archive, {}, {})
    allowed = {tuple(row) for row in elites["solution"][adding]}
    assert len(picks) and all(tuple(row) in allowed for row in picks)


def test_the_nominal_level_is_the_environment_as_registered_or_the_spaces_nominal_values(policy_file):
    from dsage_ray.types import NominalDomain

    domain = build_domain(config(**{"gym.agent": policy_file}))
    assert isinstance(domain, NominalDomain)
    registered = domain.play_nominal(seed=4)
    assert registered.level == "CartPole-v1 as registered" and registered.episodes == 10
    space, values = domain.space.nominal_level()
    played = run_episodes(space, domain.agent, values, seed=4, episodes=10)
    assert registered.mean_return == pytest.approx(played.returns.mean())
    assert registered.success_rate == pytest.approx(played.success.mean())
    assert space.params == () and values == {}  # no parameter set: CartPole's own 0.5 m pole
    heavy = build_domain(config(**{"gym.agent": policy_file, "gym.space_set": ("nominal.length = 2.0",)}))
    long_pole = heavy.play_nominal(seed=4)
    assert long_pole.level == "CartPole-v1 with length=2.0" and long_pole.mean_return != registered.mean_return


def test_with_a_floor_dsage_picks_predicted_faults_that_would_enter_even_where_cells_are_predicted():
    """``experimental.min_predicted``: of the surrogate elites that would enter, only those predicted at least the floor
    are picked (each block's largest gain), where any is; a fault space takes 0.5 unless the user sets it."""
    from dsage_ray.core.proposers import SurrogateAssisted, domain_archive
    from dsage_ray.core.seeds import RunSeeds
    from dsage_ray.qd.selection import adds_to

    assert config(**{"gym.space": "lunarlander_fault"}).experimental.min_predicted == 0.5
    assert config(**{"gym.space": "lunarlander_fault", "experimental.min_predicted": -1.0}).experimental.min_predicted == -1
    # Set to its default, the key stays: 0 is off (every elite, uniformly per block), as on any other space.
    off = config(**{"gym.space": "lunarlander_fault", "experimental.min_predicted": 0.0})
    assert off.experimental.min_predicted == 0
    assert config().experimental.min_predicted == 0.0  # cartpole declares success, not a fault
    run = config(**{"gym.measures": ("param.length", "length"), "experimental.min_predicted": 0.5})
    domain = build_domain(run)
    archive = domain_archive(domain, with_occupancy=False, seed=0)
    proposer = SurrogateAssisted(config=run, domain=domain, archive=archive, seeds=RunSeeds(seed=0), evaluator=None)
    assert not proposer.cells_known
    rng = np.random.default_rng(0)
    played = domain.random_solutions(100, rng)
    archive.add(played, np.full(100, 0.1), proposer.surrogate.predict(domain.encode(played)).measures)
    surrogate_archive = domain_archive(domain, with_occupancy=False, seed=1)
    candidates = domain.random_solutions(300, rng)
    # Predicted faults (0.9) in some cells only: elsewhere the elites would still enter (0.2 > 0.1), below the floor.
    predicted = rng.choice([0.2, 0.9], size=300, p=[0.9, 0.1])
    surrogate_archive.add(candidates, predicted, proposer.surrogate.predict(domain.encode(candidates)).measures)

    metrics = {}
    among, gain = proposer._picks_that_add(surrogate_archive, metrics)
    elites = surrogate_archive.data()
    adding = adds_to(archive, elites["objective"], elites["measures"])
    wanted = adding & (elites["objective"] >= 0.5)
    assert 0 < wanted.sum() < adding.sum() and metrics["selection_elites_that_add"] == wanted.sum()
    np.testing.assert_array_equal(np.sort(among), np.sort(elites["index"][wanted]))
    picks, _ = proposer._select(surrogate_archive, {}, {})
    allowed = {tuple(row) for row in elites["solution"][wanted]}
    assert len(picks) and all(tuple(row) in allowed for row in picks)


def test_a_fault_spaces_dsage_plays_mutants_of_its_faults_one_small_step_away():
    """A ``[fault]`` space's DSAGE adds 20 mutants of the faults found to each outer iteration's picks, each at most a
    few steps of ``experimental.mutant_sigma`` from its parent; a key the caller sets stays, and a search without a
    surrogate gets none."""
    from dsage_ray.core.proposal import Proposal
    from dsage_ray.core.proposers import SurrogateAssisted, domain_archive
    from dsage_ray.core.seeds import RunSeeds

    run = config(**{"gym.space": "lunarlander_fault"})
    assert (run.selection.elite_mutants, run.experimental.mutant_sigma) == (20, 0.01)
    assert config(**{"gym.space": "lunarlander_fault", "selection.elite_mutants": 0}).selection.elite_mutants == 0
    stepped = config(**{"gym.space": "lunarlander_fault", "experimental.mutant_sigma": 0.3})
    assert stepped.experimental.mutant_sigma == 0.3
    assert config(**{"gym.space": "lunarlander_fault", "variant": "map_elites"}).selection.elite_mutants == 0
    bitmaps = config(**{"gym.space": "lunarlander_fault", "qd.emitter": "map_elites"})  # no Gaussian step to set
    assert (bitmaps.selection.elite_mutants, bitmaps.experimental.mutant_sigma) == (20, 0.0)
    assert config().selection.elite_mutants == 0  # cartpole declares success, not a fault

    domain = build_domain(run)
    archive = domain_archive(domain, with_occupancy=False, seed=0)
    proposer = SurrogateAssisted(config=run, domain=domain, archive=archive, seeds=RunSeeds(seed=0), evaluator=None)
    rng = np.random.default_rng(0)
    faults = domain.random_solutions(30, rng)
    archive.add(faults, np.ones(30), rng.uniform(size=(30, 2)) * np.ptp(domain.measure_ranges, axis=1)
                + np.min(domain.measure_ranges, axis=1))
    proposal = Proposal(np.empty((0, domain.solution_dim), dtype=np.float32))
    proposer._add_elite_mutants(proposal)  # what propose adds beside the picks
    mutants = proposal.solutions
    assert proposal.metrics["selection_elite_mutants"] == 20
    parents = archive.data("solution")
    nearest = np.abs(mutants[:, None, :] - parents[None]).max(axis=2).min(axis=1)
    assert 0 < nearest.max() <= 5 * 0.01  # within 5 sigma of a fault: a near copy, not a fresh level
