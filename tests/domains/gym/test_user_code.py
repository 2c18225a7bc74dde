"""A gym space or level file that runs code says so before it is played, and reading it runs nothing."""

import json


def test_gym_eval_says_a_module_qualified_environment_id_runs_user_code_before_it_imports_it(tmp_path, capsys,
                                                                                             monkeypatch):
    from dsage_ray.cli import main
    from dsage_ray.domains.gym.domain import LEVEL_FORMAT
    from dsage_ray.domains.gym.space import build_space

    # gym.make("MODULE:ENV") imports MODULE: a level file naming one is code, like a setup hook.
    (tmp_path / "side_effect_env.py").write_text(
        "import pathlib, gymnasium\n"
        f"pathlib.Path({str(tmp_path / 'imported')!r}).write_text('yes')\n"
        "gymnasium.register('SideEffect-v0', entry_point='gymnasium.envs.classic_control:CartPoleEnv',\n"
        "                   max_episode_steps=20)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    space = build_space({"env": {"id": "side_effect_env:SideEffect-v0"},
                         "params": {"x": {"range": [-0.05, 0.05], "attr": "state[0]"}},
                         "success": {"return_at_least": 10}})
    assert not (tmp_path / "imported").exists()  # reading the space imports nothing
    level = tmp_path / "level.json"
    level.write_text(json.dumps({"format": LEVEL_FORMAT, "space": space.to_dict(), "values": {"x": 0.0}}))
    assert main(["gym", "eval", "--agent", "random", "--level", str(level), "--episodes", "1", "--json"]) == 0
    err = capsys.readouterr().err
    assert "this space runs user code: its environment id 'side_effect_env:SideEffect-v0' imports the module " \
           "'side_effect_env'" in err
    assert (tmp_path / "imported").read_text() == "yes"
