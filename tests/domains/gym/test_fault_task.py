"""Mazouni et al.'s LunarLander task as a space file: the setup hook's initial force, the crash fault, the measures
read at the first leg contact, and a deterministic space's one episode per evaluation."""

import json
import textwrap

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain
from dsage_ray.agents import load_agent
from dsage_ray.domains.gym.simulator import make_env, reset_env, run_episodes
from dsage_ray.domains.gym.space import SpaceError, build_space, read_space_tables

pytest.importorskip("Box2D")

#: Gymnasium's own LunarLander heuristic, a deterministic agent.
HEURISTIC = '''
from types import SimpleNamespace
from gymnasium.envs.box2d.lunar_lander import heuristic

def act(observation):
    return heuristic(SimpleNamespace(unwrapped=SimpleNamespace(continuous=False), continuous=False), observation)
'''


@pytest.fixture
def heuristic_agent(tmp_path):
    path = tmp_path / "heuristic.py"
    path.write_text(HEURISTIC)
    return f"python:{path}:act"


@pytest.fixture
def space():
    tables, source = read_space_tables("lunarlander_fault")
    return build_space(tables, source=source)


def test_the_hook_sets_the_initial_force_on_the_reset_seed_terrain(space):
    env = make_env(space, {"force_x": 0.0, "force_y": 0.0})
    try:
        still = reset_env(env, space, {"force_x": 0.0, "force_y": 0.0}, seed=0)
        terrain = env.unwrapped.helipad_y, [tuple(p) for p in env.unwrapped.sky_polys[3]]
        pushed = reset_env(env, space, {"force_x": 1000.0, "force_y": -1000.0}, seed=0)
        assert (env.unwrapped.helipad_y, [tuple(p) for p in env.unwrapped.sky_polys[3]]) == terrain
        # No force: the lander only falls; a push right and down: it moves right and falls faster.
        assert abs(still[2]) < 1e-6 and pushed[2] > 0.1 and pushed[3] < still[3] - 0.01
        left = reset_env(env, space, {"force_x": -1000.0, "force_y": 0.0}, seed=0)
        assert left[2] == pytest.approx(-pushed[2], rel=1e-3)
    finally:
        env.close()


def test_a_crash_is_a_fault_and_measures_are_read_at_first_contact(space):
    env = make_env(space, {"force_x": 0.0, "force_y": 0.0})
    agent = load_agent("random", observation_space=env.observation_space, action_space=env.action_space)
    env.close()
    signals = [space.measure(name).signal for name in ("contact_x", "contact_vy")]
    played = run_episodes(space, agent, {"force_x": 500.0, "force_y": -800.0}, seed=3, episodes=10, signals=signals)
    assert len(played.returns) == 1  # deterministic = true: one episode, whatever was asked
    crashed = played.terminated[0] and played.returns[0] < -100
    assert played.success[0] == (not crashed)
    x, vy = (played.signals[key][0] for key in sorted(played.signals))
    assert -1.5 < x < 1.5 and vy < 0


def test_an_event_that_never_happens_takes_the_fallback():
    space = build_space({
        "env": {"id": "CartPole-v1", "max_episode_steps": 20},
        "params": {"length": {"range": [0.4, 0.6], "attr": "length"}},
        "measures": {"never": {"obs": 0, "at": "first", "when": "obs[0] > 100", "otherwise": -7, "range": [-1, 1]},
                     "lowest": {"obs": 2, "at": "first", "when": "obs[0] > 100", "otherwise": "min", "range": [-1, 1]},
                     "third": {"obs": 2, "at": "first", "when": "step == 3", "otherwise": "end", "range": [-1, 1]},
                     "angle_min": {"obs": 2, "at": "min", "range": [-1, 1]}},
        "success": {"return_at_least": 10}})
    env = make_env(space, {"length": 0.5})
    agent = load_agent("random", observation_space=env.observation_space, action_space=env.action_space)
    env.close()
    signals = [m.signal for name, m in space.measures.items() if name in ("never", "lowest", "third", "angle_min")]
    played = run_episodes(space, agent, {"length": 0.5}, seed=0, episodes=4, signals=signals)
    by_name = dict(zip(("never", "lowest", "third", "angle_min"), (played.signals[k] for k in played.signals)))
    np.testing.assert_array_equal(by_name["never"], -7.0)
    np.testing.assert_array_equal(by_name["lowest"], by_name["angle_min"])
    assert not np.array_equal(by_name["third"], by_name["angle_min"])


def config(agent, **keys):
    return RunConfig.build({"domain": "gym", "preset": "tiny", "gym.space": "lunarlander_fault", "gym.agent": agent,
                            **keys})


@pytest.mark.timeout(120)
def test_a_deterministic_space_plays_one_episode_and_preflight_checks_it(heuristic_agent, capsys):
    domain = build_domain(config(heuristic_agent, **{"gym.episodes": 5}))
    domain.preflight()
    assert "this space runs user code" in capsys.readouterr().err
    assert domain.episodes == 1
    result = domain.evaluate(np.array([0.2, -0.4], dtype=np.float32), seed=11)
    again = domain.evaluate(np.array([0.2, -0.4], dtype=np.float32), seed=12)
    assert result.info == again.info and domain.work_counts(result) == {"steps": result.info["mean_length"]}
    assert domain.collection_fields()["success"] == "fault: last reward <= -100 and terminated"


@pytest.mark.timeout(120)
def test_preflight_refuses_a_random_agent_on_a_deterministic_space():
    domain = build_domain(config("random"))
    with pytest.raises(SpaceError, match=r"deterministic = true, but the box's centre played with seeds 0 and 1 "
                                         r"returned .* the environment or the agent is random") as error:
        domain.preflight()
    assert "\n" not in str(error.value)
    build_domain(config("random", **{"gym.space_set": ("env.deterministic = false",)})).preflight()


def test_a_hook_that_fails_or_is_missing_is_named_in_one_line(tmp_path):
    hook = tmp_path / "hook.py"
    hook.write_text(textwrap.dedent('''
        def broken(env, values):
            raise ValueError("no lander here")

        def wrong_shape(env, values):
            return [1.0, 2.0]
    '''))
    base = {"env": {"id": "CartPole-v1"}, "params": {"p": {"range": [0, 1], "setup": True}},
            "success": {"return_at_least": 1}}
    for function, message in (("broken", "failed: ValueError: no lander here"), ("absent", "has no function"),
                              ("wrong_shape", "returned an observation of shape (2,), not the environment's (4,)")):
        space = build_space({**base, "env": {"id": "CartPole-v1", "setup": f"python:{hook}:{function}"}})
        env = make_env(space, {"p": 0.5})
        try:
            with pytest.raises(SpaceError) as error:
                reset_env(env, space, {"p": 0.5}, seed=0)
        finally:
            env.close()
        assert message in str(error.value) and "\n" not in str(error.value)
    missing = build_space({**base, "env": {"id": "CartPole-v1", "setup": f"python:{tmp_path}/nope.py:f"}})
    env = make_env(missing, {"p": 0.5})
    with pytest.raises(SpaceError, match="not found"):
        reset_env(env, missing, {"p": 0.5}, seed=0)
    env.close()


def test_gym_eval_of_a_level_with_a_hook_says_it_runs_user_code(heuristic_agent, tmp_path, capsys):
    from dsage_ray.cli import main

    domain = build_domain(config(heuristic_agent))
    solution = np.array([0.5, 0.5], dtype=np.float32)
    level = tmp_path / "level.txt"
    level.write_text(domain.level_text(solution))
    assert main(["gym", "eval", "--agent", heuristic_agent, "--level", str(level), "--episodes", "4", "--json"]) == 0
    captured = capsys.readouterr()
    assert "this space runs user code" in captured.err and "lunarlander_force:initial_force" in captured.err
    summary = json.loads(captured.out)
    result = domain.evaluate(solution, seed=0)
    assert summary["episodes"] == 1 and summary["mean_return"] == result.info["mean_return"]

