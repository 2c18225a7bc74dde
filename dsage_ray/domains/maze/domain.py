"""The Maze domain behind the :class:`~dsage_ray.types.Domain` protocol."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.domains.maze.encoding import CHANNELS, GOAL, PATH_CHANNELS, SPARE, START, WALL, encode_levels
from dsage_ray.domains.maze.evaluate import MazeEvaluation, check_episode_memory, evaluate, evaluate_levels
from dsage_ray.domains.maze.layout import format_layout, load_layout
from dsage_ray.domains.maze.level import MazeLevel, max_steps_for
from dsage_ray.domains.maze.measures import NEEDS_REFERENCE, get_measure, get_objective
from dsage_ray.domains.maze.paths import pair_distances
from dsage_ray.domains.maze.plugin import DOMAIN, MazeConfig
from dsage_ray.types import EncodedLevels, EvaluationResult, NominalResult, Solution, Solutions

#: Episodes of the nominal check: a random walker reaches the far corner of the open room in 13% of its episodes,
#: so 50 leave it without a success once in a thousand checks (docs/GUIDE.md); batched, they cost about a second.
NOMINAL_EPISODES = 50


class MazeDomain:
    """Wall bitmaps searched for how one agent behaves on them (SPEC: the Maze).

    A solution is a flattened ``H·W`` bitmap (values > 0.5 are walls); its start and goal are the
    furthest connected pair. The agent (and the ``regression`` objective's reference agent) is loaded
    lazily, once per domain object, so building a domain is cheap and the object pickles without it.

    Args:
        config: The Maze section of a run config.
    """

    name = "maze"
    #: Bitmaps are 0/1: archives and datasets keep them as int8 (256 bytes per 16×16 elite).
    solution_dtype = np.int8
    #: An evaluation's cost grows in proportion to the agent's mean path length (50 episodes step the agent that
    #: often), plus a fixed part (building and resetting the level) worth about 200 steps in the ranked screen
    #: (``selection.screen_gain``; offset tuned on one seed, docs/DECISIONS.md).
    evaluation_cost = ("mean_path_length", 200.0)

    def __init__(self, *, config: MazeConfig):
        self.config = config
        self.height, self.width = config.height, config.width
        self.solution_dim = self.height * self.width
        self.measure_names = tuple(config.measures)
        self.work_names = tuple(config.work_names)
        # Looked up now so a bad name fails at construction; kept by name so the domain pickles.
        measures = [get_measure(name) for name in self.measure_names]
        get_objective(config.objective)
        self.measure_ranges = tuple(tuple(map(float, r)) for r in config.measure_ranges) or tuple(
            m.natural_range(self.height, self.width) for m in measures
        )
        # 0 cells means one cell per integer value of the measure (e.g. 256 for 0..256 walls).
        self.archive_dims = tuple(
            d if d > 0 else max(1, int(round(high - low)))
            for d, (low, high) in zip(config.archive_dims, self.measure_ranges)
        )
        self.occupancy_shape = (self.height, self.width)
        self.encoding_channels = len(CHANNELS) + (len(PATH_CHANNELS) if config.path_channels else 0)
        # Sizes that are not a square power of two get padded for the surrogate: padding cells
        # are marked "spare", which no real cell uses, so they never look like floor or wall.
        self.encoding_pad_channel = SPARE
        self._agent = None
        self._reference_agent = None
        self._reduced_agents: dict[str, Any] = {}

    @property
    def agent(self):
        """The agent ``config.agent`` names, loaded on first use."""
        if self._agent is None:
            from dsage_ray.domains.maze.agents import load_maze_agent

            self._agent = load_maze_agent(self.config.agent)
        return self._agent

    @property
    def reference_agent(self):
        """The agent ``config.reference`` names (the ``regression`` objective's baseline), loaded on first use."""
        if self._reference_agent is None:
            from dsage_ray.domains.maze.agents import load_maze_agent

            if not self.config.reference:
                raise ValueError("maze.reference: no reference agent configured")
            self._reference_agent = load_maze_agent(self.config.reference)
        return self._reference_agent

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        # Agents hold torch modules; each process loads its own.
        state["_agent"] = state["_reference_agent"] = None
        state["_reduced_agents"] = {}
        return state

    def level(self, solution: Solution) -> MazeLevel:
        """The level a solution describes."""
        bitmap = np.asarray(solution).reshape(self.height, self.width) > 0.5
        return MazeLevel.from_bitmap(bitmap)

    def random_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """``n`` uniformly random bitmaps, 0/1 rows of :attr:`solution_dtype`."""
        return rng.integers(0, 2, size=(n, self.solution_dim)).astype(self.solution_dtype)

    def random_valid_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """``n`` valid levels from the project's random-valid-maze distribution (the surrogate's held-out set)."""
        from dsage_ray.domains.maze.generator import random_valid_level

        levels = [random_valid_level(rng, height=self.height, width=self.width) for _ in range(n)]
        return np.array([level.walls.ravel() for level in levels], dtype=self.solution_dtype).reshape(n, -1)

    def encode(self, solutions: Solutions) -> EncodedLevels:
        return encode_levels(np.asarray(solutions).reshape(-1, self.solution_dim), self.height, self.width,
                             path_channels=self.config.path_channels)

    def run(self, solution: Solution, seed: int) -> MazeEvaluation:
        """The full evaluation of one solution (the agent is not loaded for an invalid level)."""
        level = self.level(solution)
        return self._run(level, self.agent if level.valid else None, seed)

    def run_reference(self, solution: Solution, seed: int) -> MazeEvaluation:
        """The reference agent's evaluation of one solution with the same seed and episodes as :meth:`run`.

        The seed draws the initial headings first, so both agents start every episode alike and the two
        evaluations differ only in the policy.
        """
        level = self.level(solution)
        return self._run(level, self.reference_agent if level.valid else None, seed)

    def _run(self, level: MazeLevel, agent, seed: int) -> MazeEvaluation:
        return evaluate(level, agent, episodes=self.config.episodes, seed=seed,
                        see_through_walls=self.config.see_through_walls)

    def evaluate(self, solution: Solution, seed: int) -> EvaluationResult:
        """The audited agent's numbers; with the ``regression`` objective also the reference's, under
        ``info["reference"]`` (``success_rate``, ``mean_path_length``)."""
        result = self.run(solution, seed)
        reference = (self.run_reference(solution, seed)
                     if self.config.objective in NEEDS_REFERENCE and result.valid else None)
        return self._result(result, reference)

    #: Levels per batch of :meth:`screen` (a screen of 4 or more episodes per level renders view tables of about
    #: 100 kB per 16×16 level; a shorter one gathers its views each step: ``simulator.TABLE_EPISODES``).
    SCREEN_CHUNK = 256

    def screen(self, solutions: Solutions, *, episodes: int, seed: int,
               precision: str = "fp32") -> list[EvaluationResult]:
        """A cheap first look at many solutions: :meth:`evaluate` with ``episodes`` episodes per level instead of
        the configured count, every level of a chunk stepped in one batch (``selection.screen_episodes``).
        With ``precision`` ``"bf16"`` the agents play their :meth:`~dsage_ray.agents.base.Agent.reduced_precision`
        copies, where they have one (``experimental.screen_precision``).

        With one or two episodes this costs a few percent of a full evaluation per level, and ranks ACCEL's
        50-episode mean path length far better than the surrogate does (Spearman ρ 0.91 with one episode, 0.94
        with two, on the levels of a ``cpu`` search: ``benchmarks/bench_screen.py``). The results are estimates:
        they are never added to an archive or a dataset. The screen runs where it is called (a Ray run's driver).
        """
        if precision not in ("fp32", "bf16"):
            raise ValueError(f"screen precision must be 'fp32' or 'bf16', got {precision!r}")
        levels = [self.level(solution) for solution in np.asarray(solutions).reshape(-1, self.solution_dim)]
        needs_reference = self.config.objective in NEEDS_REFERENCE
        results: list[EvaluationResult] = []
        for number, first in enumerate(range(0, len(levels), self.SCREEN_CHUNK)):
            chunk = levels[first:first + self.SCREEN_CHUNK]
            options = {"episodes": episodes, "seed": seed + number, "see_through_walls": self.config.see_through_walls}
            agent = self._screening("agent", precision) if any(level.valid for level in chunk) else None
            runs = evaluate_levels(chunk, agent, **options)
            references = (evaluate_levels(chunk, self._screening("reference_agent", precision)
                                          if agent is not None else None, **options)
                          if needs_reference else [None] * len(chunk))
            results += [self._result(run, reference if run.valid else None) for run, reference in zip(runs, references)]
        return results

    def _screening(self, role: str, precision: str):
        """The agent ``role`` names (``"agent"``, ``"reference_agent"``) as the screen plays it: for ``"bf16"`` its
        reduced-precision copy, made once, or itself when it has none."""
        agent = getattr(self, role)
        if precision == "fp32":
            return agent
        if role not in self._reduced_agents:
            self._reduced_agents[role] = agent.reduced_precision() or agent
        return self._reduced_agents[role]

    def _result(self, result: MazeEvaluation, reference: MazeEvaluation | None) -> EvaluationResult:
        info = {
            key: value for key, value in result.to_dict().items()
            if key in ("success_rate", "mean_path_length", "episode_lengths", "successes",
                       "optimal_path_length", "start", "goal", "valid", "explored_fraction", "repeated_visits")
        }
        if reference is not None:
            info["reference"] = {"success_rate": reference.success_rate,
                                 "mean_path_length": reference.mean_path_length}
        return EvaluationResult(
            objective=float(get_objective(self.config.objective)(result, reference)),
            measures=np.array([get_measure(name).fn(result) for name in self.measure_names], dtype=np.float64),
            occupancy=result.occupancy,
            info=info,
        )

    def render(self, solution: Solution, occupancy: np.ndarray | None = None, *, title: str | None = None,
               occupancy_max: float | None = None) -> bytes:
        """A PNG of the level, with ``occupancy`` overlaid when given.

        Args:
            solution: The level's bitmap.
            occupancy: Visits per cell to overlay.
            title: Figure title.
            occupancy_max: Top of the colour scale (default: this level's own maximum); one value for a
                set of pictures makes their colours comparable.
        """
        from dsage_ray.domains.maze.render import render_level

        return render_level(self.level(solution), occupancy, title=title, occupancy_max=occupancy_max)

    # ------------------------------------------------------------------------------- audits
    # What the domain-generic audit (dsage_ray.audit) asks of a domain (types.AuditableDomain); the
    # audit's defaults are in the registration (plugin.DOMAIN.audit).

    @classmethod
    def audit_values(cls, *, agent: str, reference: str | None = None, objective: str | None = None,
                     measures: Sequence[str] | None = None) -> dict[str, Any]:
        """The dotted config keys of a Maze audit (:func:`dsage_ray.audit.collection.audit_config`).

        Args:
            agent: The audited agent's spec.
            reference: A reference agent's spec: the audit then searches for regressions of ``agent``
                against it (objective ``regression``, the default with a reference).
            objective: One of the registration's audit objectives (default ``failure_rate``, or ``regression``).
            measures: Measure names (default the registration's audit measures); archive cells are one per integer
                value of each measure's natural range, 50 for the fractions in ``[0, 1]``.

        Raises:
            ValueError: An objective an audit cannot use, or a reference without ``regression`` (or the reverse).
        """
        audit = DOMAIN.audit
        objective = objective or ("regression" if reference else "failure_rate")
        if objective not in audit.objectives:
            raise ValueError(f"maze audit objective must be one of {', '.join(map(repr, audit.objectives))}, "
                             f"got {objective!r}")
        if (objective == "regression") != bool(reference):
            raise ValueError("the 'regression' objective needs a reference agent (--reference), and a reference "
                             f"agent needs the 'regression' objective (got objective {objective!r})")
        measures = tuple(measures or audit.measures)
        for name in measures:
            get_measure(name)

        def cells(name: str) -> int:
            low, high = get_measure(name).natural_range(16, 16)
            return 50 if high - low <= 1 else int(round(high - low))

        # The default measures (wall count, optimal path) are properties of the level: taken from it, every pick
        # lands in the cell the inner loop chose it for (docs/DECISIONS.md).
        values = {"maze.agent": agent, "maze.reference": reference or "", "maze.objective": objective,
                  "maze.measures": measures, "maze.archive_dims": tuple(cells(m) for m in measures),
                  "surrogate.exact_level_values": True}
        if "mean_path_length" not in measures:
            # The cpu preset predicts the path length as the occupancy sum, blended with the random walker's
            # prior; without that measure there is neither.
            values["surrogate.occupancy_sum_measure"] = ""
            values["surrogate.prior_measure"] = ""
        return values

    def surrogate_prior(self, measure: str):
        """The random walker's hitting time for ``mean_path_length`` (:mod:`dsage_ray.domains.maze.prior`)."""
        from dsage_ray.domains.maze.prior import walker_prior

        return walker_prior(measure)

    def level_values(self, encoded: EncodedLevels) -> dict[str, np.ndarray]:
        """What a level fixes by itself, from its encoding: ``num_walls``, ``optimal_path_length`` and the
        ``validity`` objective.

        An encoded level has a start (and a goal) only when two empty cells connect, which is what makes it valid.
        """
        encoded = np.asarray(encoded)[:, :, :self.config.height, :self.config.width]
        values = {"num_walls": encoded[:, WALL].sum(axis=(1, 2))}
        flat = encoded.reshape(len(encoded), encoded.shape[1], -1)
        valid = flat[:, START].max(axis=1, initial=0.0) > 0.5
        if "optimal_path_length" in self.measure_names:
            starts = np.where(valid, flat[:, START].argmax(axis=1), -1)
            lengths = pair_distances(encoded[:, WALL] > 0.5, starts, flat[:, GOAL].argmax(axis=1))
            values["optimal_path_length"] = np.maximum(lengths, 0).astype(np.float32)
        if self.config.objective == "validity":
            values["objective"] = valid.astype(np.float32)
        return values

    def preflight(self) -> None:
        """Loads the agent (and the reference) now, so a bad spec fails in one line before any search.

        Raises:
            ValueError: An agent that cannot be loaded (:class:`~dsage_ray.agents.AgentError` or a file error).
            ResourceError: ``episodes`` side by side would not fit in memory.
        """
        check_episode_memory(self.config.episodes, (self.height, self.width))
        roles = [("agent", self.config.agent, "agent")]
        if self.config.reference:
            roles.append(("reference agent", self.config.reference, "reference_agent"))
        for role, spec, attribute in roles:
            try:
                getattr(self, attribute)
            except (ValueError, OSError) as exc:  # AgentError is a ValueError
                raise ValueError(f"{role} {spec!r}: {exc}") from None

    def play_nominal(self, *, seed: int) -> NominalResult:
        """The agent in an open room (:class:`~dsage_ray.types.NominalDomain`): no interior wall, the start and goal
        the furthest pair (opposite corners). Its return is MiniGrid's reward, ``1 − 0.9·steps/max_steps`` on
        reaching the goal, else 0."""
        level = MazeLevel.from_bitmap(np.zeros((self.height, self.width), dtype=bool))
        played = evaluate(level, self.agent, episodes=NOMINAL_EPISODES, seed=seed,
                          see_through_walls=self.config.see_through_walls)
        rewards = np.where(played.successes, 1.0 - 0.9 * played.episode_lengths / played.max_steps, 0.0)
        return NominalResult(
            level=f"an open {self.height}x{self.width} room (start {level.start}, goal {level.goal})",
            return_name="MiniGrid reward", mean_return=float(rewards.mean()), return_std=float(rewards.std(ddof=1)),
            success_rate=float(played.success_rate), episodes=NOMINAL_EPISODES, seed=int(seed),
            expected_return=self.agent.expected_return, expected_return_source=self.agent.expected_return_source,
            causes=(f"observations other than in training (here see_through_walls = "
                    f"{str(self.config.see_through_walls).lower()}), a checkpoint of another environment, or a loader "
                    f"that drops its preprocessing"))

    @property
    def agent_spec(self) -> str:
        return self.config.agent

    @property
    def reference_spec(self) -> str | None:
        return self.config.reference or None

    @property
    def episodes(self) -> int:
        return self.config.episodes

    def is_valid(self, solution: Solution) -> bool:
        """A start and a goal connected by a path (invalid levels never reach a collection)."""
        return self.level(solution).valid

    def level_text(self, solution: Solution) -> str:
        """The layout file of a valid level (``dsage-ray maze eval --layout`` reads it)."""
        return format_layout(self.level(solution))

    def work_counts(self, result: EvaluationResult) -> dict[str, float]:
        """``steps``: the agent's steps over all the evaluation's episodes (what the simulator spent its time on)."""
        return {"steps": float(sum(result.info.get("episode_lengths", ())))}

    def success_rate(self, result: EvaluationResult) -> float:
        """The share of the episodes that reached the goal."""
        return float(result.info["success_rate"])

    def reference_numbers(self, result: EvaluationResult) -> dict[str, float] | None:
        """The reference agent's ``success_rate`` and ``mean_path_length`` of a ``regression`` evaluation."""
        reference = result.info.get("reference")
        return None if reference is None else {key: float(value) for key, value in reference.items()}

    def entry_solution(self, entry: dict[str, Any], folder: Path) -> Solution:
        """The bitmap of a collection entry's layout file (:meth:`read_level`)."""
        return self.read_level(Path(folder) / entry["level_file"])

    def read_level(self, path: str | Path) -> Solution:
        """The bitmap of a layout file :meth:`level_text` wrote.

        Raises:
            ValueError: Not a layout of this size, or start and goal moved off the level's furthest pair
                (the domain places them there, so it would evaluate another level than the file shows).
        """
        level = load_layout(path)
        solution = np.asarray(level.walls, dtype=self.solution_dtype).ravel()
        if solution.size != self.solution_dim:
            raise ValueError(f"{path}: a {level.walls.shape[0]}x{level.walls.shape[1]} layout, the domain's levels "
                             f"are {self.height}x{self.width}")
        placed = self.level(solution)
        if (placed.start, placed.goal) != (level.start, level.goal):
            raise ValueError(f"{path}: start/goal are not the level's furthest pair (edited by hand?); compare "
                             f"evaluates collection levels as the audit wrote them")
        return solution

    def reproduce_command(self, level_file: str | Path, *, seed: int) -> str:
        """The shell command that re-runs this domain's evaluation of the layout in ``level_file``."""
        command = ["dsage-ray", "maze", "eval", "--agent", self.config.agent, "--layout", str(level_file),
                   "--episodes", str(self.config.episodes), "--seed", str(int(seed))]
        if not self.config.see_through_walls:
            command.append("--no-see-through-walls")
        return shlex.join(command)

    def render_evaluation(self, solution: Solution, result: EvaluationResult, *, title: str | None = None,
                          occupancy_max: float | None = None) -> bytes:
        """The level with the agent's occupancy from ``result``."""
        return self.render(solution, result.occupancy, title=title, occupancy_max=occupancy_max)

    def collection_fields(self) -> dict[str, Any]:
        """Maze settings at the top level of a collection (beside the generic keys)."""
        # The step limit a failed episode counts in mean_path_length (the report explains the number).
        return {"see_through_walls": bool(self.config.see_through_walls),
                "max_steps": max_steps_for(self.height, self.width)}

    def entry_fields(self, solution: Solution, result: EvaluationResult, *, level_file: str) -> dict[str, Any]:
        """The Maze numbers of a collection entry beside the generic ones (``layout_file`` and ``layout``
        for collections written before level files had a domain-neutral name)."""
        level, info = self.level(solution), result.info
        return {
            "layout_file": level_file,
            "layout": format_layout(level),
            "start": list(level.start),
            "goal": list(level.goal),
            "num_walls": level.num_walls,
            "optimal_path_length": int(info["optimal_path_length"]),
            "mean_path_length": float(info["mean_path_length"]),
            "episode_lengths": [int(x) for x in info["episode_lengths"]],
            "explored_fraction": float(info["explored_fraction"]),
            "repeated_visits": float(info["repeated_visits"]),
        }

