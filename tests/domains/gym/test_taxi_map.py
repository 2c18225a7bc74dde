"""``dsage_ray/TaxiMap-v0``: Taxi's rules on any map drawing, the faults it reports, and the shipped
``taxi_large_fault`` space (Mazouni et al.'s Taxi task) played by a Q-table."""

import numpy as np
import pytest

import gymnasium as gym

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain
from dsage_ray.domains.gym.envs import TAXI_MAP, register
from dsage_ray.domains.gym.envs.taxi_map import TaxiMapEnv
from dsage_ray.domains.gym.space import SpaceError

register()

#: A 3 x 4 drawing of our own: locations A (0, 0), B (0, 3) and C (2, 1); a wall east of (0, 1) and (1, 1).
SMALL = """\
+-------+
|A: | :B|
| : | : |
| :C: : |
+-------+
"""


def test_on_gymnasium_s_map_it_is_taxi_v3_step_by_step():
    reference = gym.make("Taxi-v3")
    ours = gym.make(TAXI_MAP, end_on_fault=False)
    rng = np.random.default_rng(0)
    for episode in range(60):
        state, _ = reference.reset(seed=episode)
        row, column, passenger, destination = reference.unwrapped.decode(state)
        mine, _ = ours.reset(options={"row": row, "column": column, "passenger": passenger,
                                      "destination": destination})
        assert mine == state
        for _ in range(200):
            action = int(rng.integers(6))
            expected, got = reference.step(action), ours.step(action)
            assert got[:4] == expected[:4]
            if expected[2] or expected[3]:
                break


def test_it_reports_crashes_illegal_actions_and_the_moves_with_and_without_the_passenger(tmp_path):
    (tmp_path / "small.txt").write_text(SMALL)
    env = TaxiMapEnv(map_file=str(tmp_path / "small.txt"))
    assert (env.rows, env.columns, env.locations) == (3, 4, [(0, 0), (0, 3), (2, 1)])
    assert env.observation_space.n == 3 * 4 * 4 * 3
    state, info = env.reset(options={"row": 0, "column": 0, "passenger": 0, "destination_offset": 2})
    assert env.destination == 2 and state == env.encode(0, 0, 0, 2)  # (0 + 2) mod 3
    assert (info["moves_empty"], info["moves_loaded"], info["fault"]) == (0, 0, False)
    _, reward, terminated, _, info = env.step(4)  # pick up at A
    assert (reward, terminated, info["fault"]) == (-1.0, False, False) and env.passenger == 3
    for action in (0, 0, 2):  # south, south, east: to C (2, 1), loaded
        _, reward, terminated, _, info = env.step(action)
    assert env.taxi == (2, 1) and (info["moves_empty"], info["moves_loaded"]) == (0, 3)
    _, reward, terminated, _, info = env.step(5)
    assert (reward, terminated, info["fault"]) == (20.0, True, False)

    env.reset(options={"row": 0, "column": 1, "passenger": 1, "destination": 2})
    _, reward, terminated, _, info = env.step(2)  # east of (0, 1) is a wall
    assert env.taxi == (0, 1) and (reward, terminated, info["crash"], info["fault"]) == (-1.0, True, True, True)
    assert info["moves_empty"] == 1  # the move into the wall counts, as in their behaviour
    env.reset(options={"row": 0, "column": 1, "passenger": 1, "destination": 2})
    _, reward, terminated, _, info = env.step(1)  # north off the map
    assert info["crash"] and terminated
    env.reset(options={"row": 1, "column": 1, "passenger": 1, "destination": 2})
    _, reward, terminated, _, info = env.step(5)  # a drop-off with no passenger
    assert (reward, terminated, info["illegal"], info["crash"]) == (-10.0, True, True, False)

    patient = TaxiMapEnv(map_file=str(tmp_path / "small.txt"), end_on_fault=False)
    patient.reset(options={"row": 1, "column": 1, "passenger": 1, "destination": 2})
    assert patient.step(4)[1:4] == (-10.0, False, False)  # Taxi's own rule: the episode goes on


def test_a_drop_off_at_another_location_leaves_the_passenger_there(tmp_path):
    (tmp_path / "small.txt").write_text(SMALL)
    env = TaxiMapEnv(map_file=str(tmp_path / "small.txt"))
    env.reset(options={"row": 0, "column": 0, "passenger": 0, "destination": 1})
    env.step(4)
    for action in (0, 0, 2):
        env.step(action)
    _, reward, terminated, _, info = env.step(5)  # at C, not the destination B
    assert (reward, terminated, info["fault"], env.passenger) == (-1.0, False, False, 2)
    assert env.step(2)[4]["moves_empty"] == 1  # the passenger is out: moves count as empty again


@pytest.mark.parametrize("options, message", [
    ({"row": 3}, "row 3 is not in [0, 2] on map"),
    ({"passenger": 1, "destination": 1}, "the passenger starts at the destination"),
    ({"destination_offset": 3}, "destination_offset 3 is not in [1, 2]"),
    ({"destination": 1, "destination_offset": 1}, "give destination or destination_offset, not both"),
    ({"colour": 1}, "unknown ['colour']"),
])
def test_bad_reset_options_are_refused_naming_the_option(tmp_path, options, message):
    (tmp_path / "small.txt").write_text(SMALL)
    with pytest.raises(ValueError) as caught:
        TaxiMapEnv(map_file=str(tmp_path / "small.txt")).reset(options=options)
    assert message in str(caught.value)


@pytest.mark.parametrize("text, message", [
    ("+---+\n|A: |\n+--+\n", "not a Taxi drawing"),
    ("+---+\n|A: |\n+---+\n", "1 location(s)"),
    ("", "not a Taxi drawing"),
])
def test_a_file_that_is_not_a_taxi_drawing_is_refused(tmp_path, text, message):
    (tmp_path / "map.txt").write_text(text)
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        TaxiMapEnv(map_file=str(tmp_path / "map.txt"))
    with pytest.raises(ValueError, match="cannot be read"):
        TaxiMapEnv(map_file=str(tmp_path / "missing.txt"))


def test_its_frame_shows_the_map(tmp_path):
    (tmp_path / "small.txt").write_text(SMALL)
    env = TaxiMapEnv(map_file=str(tmp_path / "small.txt"), render_mode="rgb_array")
    env.reset(options={"row": 1, "column": 2, "passenger": 0, "destination": 1})
    frame = env.render()
    assert frame.shape == (3 * 24 + 1, 4 * 24 + 1, 3) and frame.dtype == np.uint8
    assert tuple(frame[24 + 12, 2 * 24 + 12]) == (240, 190, 0)  # the empty taxi, yellow
    assert tuple(frame[12, 2 * 24]) == (0, 0, 0)  # the wall east of (0, 1)


def large_map(path):
    """An 18 x 13 drawing with 11 locations and a few walls: the shape of Mazouni et al.'s map, not theirs."""
    letters = {(0, 0), (0, 6), (3, 2), (5, 12), (8, 8), (9, 4), (11, 0), (12, 7), (14, 10), (16, 3), (17, 12)}
    lines = ["+" + "-" * 25 + "+"]
    for r in range(18):
        cells = ["ABCDEFGHIJK"[sorted(letters).index((r, c))] if (r, c) in letters else " " for c in range(13)]
        sides = ["|" if (r + c) % 7 == 3 else ":" for c in range(12)]
        lines.append("|" + "".join(cell + side for cell, side in zip(cells, sides + ["|"])))
    lines.append(lines[0])
    path.write_text("\n".join(lines) + "\n")
    return path


def config(tmp_path, agent):
    return RunConfig.build({"domain": "gym", "preset": "tiny", "gym.space": "taxi_large_fault", "gym.agent": agent,
                            "gym.env_args": (f"map_file={large_map(tmp_path / 'large.txt')}",)})


def test_the_shipped_space_plays_a_q_table_one_episode_a_level_with_the_peers_faults_and_grid(tmp_path):
    table = np.zeros((18 * 13 * 12 * 11, 6))
    table[:, 1] = 1.0  # always north: a crash at the top edge, after `row` moves
    np.save(tmp_path / "north.npy", table)
    domain = build_domain(config(tmp_path, f"qtable:{tmp_path / 'north.npy'}"))
    domain.preflight()
    assert domain.archive_dims == (406, 59)
    level = domain.space.solution({"row": 5, "column": 2, "passenger": 3, "destination_offset": 4})
    result = domain.evaluate(level, seed=0)
    assert result.objective == 1.0 and result.info["mean_return"] == -6.0  # 5 moves north, then the edge
    assert result.measures.tolist() == [6.0, 0.0]  # six moves without the passenger (the crash counts)


def test_without_the_map_file_the_space_stops_in_one_line_naming_the_map():
    table_spec = "random"
    domain = build_domain(RunConfig.build({"domain": "gym", "preset": "tiny", "gym.space": "taxi_large_fault",
                                           "gym.agent": table_spec}))
    with pytest.raises((SpaceError, ValueError)) as caught:
        domain.preflight()
    assert "Gymnasium's 5 x 5 Taxi map (no map_file given)" in str(caught.value)


def test_decode_inverts_encode(tmp_path):
    (tmp_path / "small.txt").write_text(SMALL)
    env = TaxiMapEnv(map_file=str(tmp_path / "small.txt"))
    states = [env.encode(r, c, p, d) for r in range(3) for c in range(4) for p in range(4) for d in range(3)]
    assert sorted(states) == list(range(env.observation_space.n))
    assert all(env.encode(*env.decode(s)) == s for s in states)
    env.set_state(env.encode(2, 1, 3, 0))
    assert (env.taxi, env.passenger, env.destination) == ((2, 1), 3, 0)
