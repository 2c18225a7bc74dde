"""The gym domain behind the :class:`~dsage_ray.types.Domain` protocol: any Gymnasium environment, re-parameterised."""

from __future__ import annotations

import json
import shlex
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.domains.gym.plugin import DOMAIN, GymConfig
from dsage_ray.domains.gym.simulator import (check_episode_memory, make_env, reset_env, run_episodes, signal_key,
                                             step_limit)
from dsage_ray.domains.gym.space import EnvSpace, SpaceError, build_space, load_space
from dsage_ray.types import EncodedLevels, EvaluationResult, NominalResult, Solution, Solutions

#: The ``format`` of a gym level file: the space it belongs to and the level's values, as JSON.
LEVEL_FORMAT = "dsage_ray.gym.level/1"
#: Episodes of the nominal check (as many as the RL Zoo's evaluations.npz rows hold; docs/GUIDE.md).
NOMINAL_EPISODES = 10


class GymDomain:
    """Levels are points of ``[-1, 1]^P``, one coordinate per parameter of the space; an evaluation plays the agent
    for ``episodes`` episodes of the environment built with the level's values.

    The objective is the share of failed episodes (the space's success test). The surrogate reads the parameter
    vector (encoded as ``(n, P, 1, 1)``, which the surrogate reads with a multilayer perceptron) and, two-stage,
    first predicts the histogram of the space's two occupancy coordinates.

    Args:
        config: The ``gym`` section of a run config (its ``complete`` has filled the measures).
    """

    name = "gym"
    solution_dtype = np.float32
    #: Emitters keep their samples in this box; the domain clips what falls outside.
    solution_bounds = (-1.0, 1.0)
    encoding_pad_channel = 0

    def __init__(self, *, config: GymConfig):
        self.config = config
        self.space: EnvSpace = load_space(config)
        self.solution_dim = self.space.dim
        self.encoding_channels = self.space.dim
        self.measure_names = tuple(config.measures)
        measures = [self.space.measure(name) for name in self.measure_names]
        self.measure_ranges = (tuple(tuple(map(float, r)) for r in config.measure_ranges)
                               or tuple((m.low, m.high) for m in measures))
        self.archive_dims = tuple(config.archive_dims) or tuple(m.cells for m in measures)
        self.occupancy_shape = self.space.occupancy_shape
        self._signals = tuple(m.signal for m in measures)
        self._agent = None

    def __getstate__(self) -> dict[str, Any]:
        # The agent holds torch modules or user code; each process loads its own.
        return {**self.__dict__, "_agent": None}

    # ------------------------------------------------------------------------------- search space

    def random_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """The generator: uniform over the box, so every parameter uniform over its range."""
        return rng.uniform(-1.0, 1.0, size=(n, self.solution_dim)).astype(self.solution_dtype)

    random_valid_solutions = random_solutions  # every point of the box is a level

    def encode(self, solutions: Solutions) -> EncodedLevels:
        """The parameter vector, clipped to the box, as ``(n, P, 1, 1)``: the surrogate's multilayer perceptron input."""
        solutions = np.clip(np.asarray(solutions, dtype=np.float32).reshape(-1, self.solution_dim), -1.0, 1.0)
        return solutions[:, :, None, None]

    def level_values(self, encoded: np.ndarray) -> dict[str, np.ndarray]:
        """The measures that are parameters, exact from the encoded levels (``surrogate.exact_level_values``)."""
        units = np.asarray(encoded, dtype=np.float64)[:, :, 0, 0]
        index = {p.name: i for i, p in enumerate(self.space.params)}
        return {name: self.space.params[index[signal.key]].numbers(units[:, index[signal.key]]).astype(np.float32)
                for name, signal in zip(self.measure_names, self._signals) if signal.source == "param"}

    def values(self, solution: Solution) -> dict[str, Any]:
        """``{parameter name: value}`` of a level."""
        return self.space.values(solution)

    # ----------------------------------------------------------------------------------- simulator

    @property
    def agent(self):
        """The agent ``config.agent`` names, loaded on first use against the environment's spaces."""
        if self._agent is None:
            from dsage_ray.agents import load_agent

            env = make_env(self.space, self.space.values(np.zeros(self.solution_dim)))
            try:
                self._agent = load_agent(self.config.agent, observation_space=env.observation_space,
                                         action_space=env.action_space, env=env)
            finally:
                env.close()
        return self._agent

    def evaluate(self, solution: Solution, seed: int, *, episodes: int | None = None) -> EvaluationResult:
        """Plays the agent on the level; the objective is its failure rate (deterministic for ``seed``)."""
        values = self.space.values(solution)
        played = run_episodes(self.space, self.agent, values, seed=seed, episodes=episodes or self.episodes,
                              signals=self._signals)
        success_rate = float(played.success.mean())
        return EvaluationResult(
            objective=1.0 - success_rate,
            measures=np.array([played.signals[signal_key(s)].mean() for s in self._signals], dtype=np.float64),
            occupancy=played.occupancy,
            info={"success_rate": success_rate, "mean_return": float(played.returns.mean()),
                  "min_return": float(played.returns.min()), "mean_length": float(played.lengths.mean()),
                  "terminated": float(played.terminated.mean()), "values": _plain(values)},
        )

    def work_counts(self, result: EvaluationResult) -> dict[str, float]:
        """Environment steps (what an evaluation's time grows with)."""
        return {"steps": result.info["mean_length"] * self.episodes}

    work_names = GymConfig.work_names

    # ---------------------------------------------------------------------------------- rendering

    def render(self, solution: Solution, occupancy: np.ndarray | None = None) -> bytes:
        from dsage_ray.domains.gym.render import level_picture

        return level_picture(self.space, self.space.values(solution), occupancy=occupancy)

    def render_evaluation(self, solution: Solution, result: EvaluationResult, *, title: str | None = None,
                          occupancy_max: float | None = None) -> bytes:
        from dsage_ray.domains.gym.render import level_picture

        return level_picture(self.space, self.space.values(solution), occupancy=result.occupancy, title=title,
                             occupancy_max=occupancy_max, result=result)

    # -------------------------------------------------------------------------------------- audits

    @classmethod
    def audit_values(cls, *, agent: str, reference: str | None = None, objective: str | None = None,
                     measures: Sequence[str] | None = None) -> dict[str, Any]:
        """The dotted config keys of an audit of ``agent`` (the measures default to the space's)."""
        from dsage_ray.agents.kinds import FORMS

        if reference:
            raise ValueError("gym audits play one agent: no --reference (compare two on a collection with "
                             "dsage-ray compare)")
        objective = objective or DOMAIN.audit.objectives[0]
        if objective not in DOMAIN.audit.objectives:
            raise ValueError(f"gym audit objective must be one of {DOMAIN.audit.objectives}, got {objective!r}")
        kind = agent.partition(":")[0]
        if kind not in DOMAIN.agents.forms:
            raise ValueError(f"gym agent {agent!r}: unknown kind {kind!r} (known: {', '.join(FORMS.values())})")
        values: dict[str, Any] = {"gym.agent": agent, "gym.objective": objective}
        if measures:
            values["gym.measures"] = tuple(measures)
        return values

    def preflight(self) -> None:
        """Checks everything before the search: the environment and its parameters (one reset at each corner of
        the box and its centre), the agent against the environment's spaces, and the measures (one episode); a
        space declared deterministic plays that episode again with another seed, which must give the same return
        and length. A space that runs user code (a setup hook, a ``MODULE:ENV`` id) says so first.

        Raises:
            SpaceError, AgentError: What is wrong, in one line.
            ResourceError: ``episodes`` side by side would not fit in memory.
        """
        import sys

        from dsage_ray.domains.gym.setup_hook import user_code_notices

        for notice in user_code_notices(self.space):
            print(notice, file=sys.stderr)
        check_episode_memory(self.config.episodes)
        for corner in (-1.0, 0.0, 1.0):
            values = self.space.values(np.full(self.solution_dim, corner))
            env = make_env(self.space, values)
            try:
                step_limit(env, self.space)
                reset_env(env, self.space, values, seed=0)
            finally:
                env.close()
        centre = np.zeros(self.solution_dim, dtype=self.solution_dtype)
        first = self.evaluate(centre, seed=0, episodes=1)
        if self.space.deterministic:
            check_deterministic(self.space, first, self.evaluate(centre, seed=1, episodes=1))

    def play_nominal(self, *, seed: int) -> NominalResult:
        """The agent on the nominal level (:class:`~dsage_ray.types.NominalDomain`): the environment as registered,
        with the space's fixed ``gym.make`` keywords and its ``[nominal]`` values, nothing else set."""
        space, values = self.space.nominal_level()
        episodes = 1 if self.space.deterministic else NOMINAL_EPISODES
        played = run_episodes(space, self.agent, values, seed=seed, episodes=episodes)
        settings = [f"{key}={value}" for key, value in {**space.env_args, **values}.items()]
        agent = self.agent
        return NominalResult(
            level=f"{space.env_id} " + (f"with {', '.join(settings)}" if settings else "as registered"),
            mean_return=float(played.returns.mean()),
            return_std=float(played.returns.std(ddof=1)) if episodes > 1 else 0.0,
            success_rate=float(played.success.mean()), episodes=episodes, seed=int(seed),
            expected_return=agent.expected_return, expected_return_source=agent.expected_return_source,
            causes=(f"observation preprocessing not applied (normalisation statistics, frame stacking, the training "
                    f"wrappers), an environment version other than the one it was trained on (here {space.env_id}), "
                    f"or actions sampled from a policy meant to be played greedily (?greedy=1)"))

    @property
    def agent_spec(self) -> str:
        return self.config.agent

    @property
    def reference_spec(self) -> None:
        return None

    @property
    def episodes(self) -> int:
        """Episodes per evaluation: one where the space is declared deterministic (the others would repeat it)."""
        return 1 if self.space.deterministic else self.config.episodes

    def is_valid(self, solution: Solution) -> bool:
        return True

    def success_rate(self, result: EvaluationResult) -> float:
        return float(result.info["success_rate"])

    def reference_numbers(self, result: EvaluationResult) -> None:
        return None

    def level_text(self, solution: Solution) -> str:
        """A level file: the level's values and the whole space, as JSON (``dsage-ray gym eval`` reads it alone)."""
        return json.dumps({"format": LEVEL_FORMAT, "values": _plain(self.space.values(solution)),
                           "space": self.space.to_dict()}, indent=1) + "\n"

    def entry_solution(self, entry: dict[str, Any], folder: Path) -> Solution:
        path = Path(folder) / entry["level_file"]
        space, values = read_level(path)
        if space.env_id != self.space.env_id or [p.name for p in space.params] != [p.name for p in self.space.params]:
            raise SpaceError(f"{path}: a level of {space.env_id} with parameters {[p.name for p in space.params]}, not "
                             f"of this audit's {self.space.env_id} ({[p.name for p in self.space.params]})")
        return self.space.solution(values)

    def reproduce_command(self, level_file: str | Path, *, seed: int) -> str:
        return shlex.join(["dsage-ray", "gym", "eval", "--agent", self.config.agent, "--level", str(level_file),
                           "--seed", str(seed), "--episodes", str(self.episodes)])

    def collection_fields(self) -> dict[str, Any]:
        env = make_env(self.space, self.space.values(np.zeros(self.solution_dim)))
        try:
            limit = step_limit(env, self.space)
        finally:
            env.close()
        success = self.space.fault.describe() if self.space.fault is not None else self.space.success.describe()
        return {"env": self.space.env_id, "success": success, "max_steps": limit,
                "parameters": [p.describe() for p in self.space.params]}

    def entry_fields(self, solution: Solution, result: EvaluationResult, *, level_file: str) -> dict[str, Any]:
        values = result.info["values"]
        numbers = {f"param.{name}": value for name, value in values.items()
                   if isinstance(value, (int, float)) and not isinstance(value, bool)}
        return {"mean_return": result.info["mean_return"], "min_return": result.info["min_return"],
                "mean_length": result.info["mean_length"], **numbers, "values": values}


def check_deterministic(space: EnvSpace, first: EvaluationResult, again: EvaluationResult) -> None:
    """Refuses a space declared deterministic whose level, played with two seeds, did two different things.

    Raises:
        SpaceError: The returns or lengths differ (one line naming both).
    """
    a, b = first.info, again.info
    if a["mean_return"] != b["mean_return"] or a["mean_length"] != b["mean_length"]:
        raise SpaceError(f"{space.source}: [env] deterministic = true, but the box's centre played with seeds 0 and 1 "
                         f"returned {a['mean_return']:.6g} and {b['mean_return']:.6g} in {a['mean_length']:g} and "
                         f"{b['mean_length']:g} steps: the environment or the agent is random given a level (fix the "
                         f"reset with [env] reset_seed, play a greedy agent, or drop deterministic)")


def read_level(path: str | Path) -> tuple[EnvSpace, dict[str, Any]]:
    """The space and values of a gym level file (:meth:`GymDomain.level_text`).

    Raises:
        SpaceError: Not such a file (named).
    """
    path = Path(path)
    try:
        level = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SpaceError(f"level file {str(path)!r}: not a gym level ({type(exc).__name__})") from None
    if not isinstance(level, dict) or level.get("format") != LEVEL_FORMAT or not isinstance(level.get("values"), dict):
        raise SpaceError(f"level file {str(path)!r}: not a gym level (expected JSON with format {LEVEL_FORMAT!r})")
    space = build_space(level.get("space"), source=str(path))
    space.solution(level["values"])  # names and ranges checked
    return space, level["values"]


def _plain(values: dict[str, Any]) -> dict[str, Any]:
    """Parameter values as JSON scalars (numpy scalars become Python ones)."""
    return {name: value.item() if isinstance(value, np.generic) else value for name, value in values.items()}
