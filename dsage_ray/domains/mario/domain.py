"""The Mario domain behind the :class:`~dsage_ray.types.Domain` protocol (SPEC: Mario)."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.domains.mario.encoding import PADDED_SIZE, one_hot_levels
from dsage_ray.domains.mario.evaluate import MEASURES, MarioEvaluation, evaluate_level
from dsage_ray.domains.mario.plugin import DOMAIN, MarioConfig
from dsage_ray.domains.mario.render import level_png
from dsage_ray.domains.mario.tiles import (CHAR_TO_INDEX, EMPTY, LEVEL_HEIGHT, LEVEL_WIDTH, NUM_TILES, SKY_ROWS,
                                           indices_to_string)
from dsage_ray.types import EncodedLevels, EvaluationResult, NominalResult, Solution, Solutions

#: Natural range of each measure, used when the config gives no ``measure_ranges``.
#: Sky tiles and jumps follow the paper; kills follow its appendix ([0, 25]).
NATURAL_RANGES: dict[str, tuple[float, float]] = {
    "sky_tiles": (0.0, 150.0),
    "mean_jumps": (0.0, 100.0),
    "enemies_killed": (0.0, 25.0),
}

#: The agent specs a Mario audit accepts (the domain has one agent: the A* planner).
AGENT_SPECS = ("astar", "astar:ITERATIONS")


def flat_level(width: int = LEVEL_WIDTH) -> np.ndarray:
    """The nominal Mario level: ``width`` columns of sky over two rows of ground, nothing else."""
    level = np.full((LEVEL_HEIGHT, width), EMPTY, dtype=np.int64)
    level[-2:] = CHAR_TO_INDEX["X"]
    return level


def parse_agent_spec(spec: str) -> int | None:
    """The A* iterations per tick a Mario agent spec names: ``astar`` (None: keep the config's) or
    ``astar:ITERATIONS`` (0: the stock wall-clock timer).

    Raises:
        ValueError: Any other spec; the message lists the ones that exist.
    """
    kind, _, iterations = spec.strip().partition(":")
    if kind == "astar" and not iterations:
        return None
    if kind == "astar" and iterations.isdigit():
        return int(iterations)
    raise ValueError(f"unknown Mario agent {spec!r} (known: {', '.join(AGENT_SPECS)}; "
                     f"ITERATIONS is a non-negative integer, 0 for the stock 40 ms timer)")


class MarioDomain:
    """GAN latents searched for how Robin Baumgarten's A* agent plays the levels they decode to.

    A solution is a 32-d latent; the generator (loaded lazily, once per domain object) decodes it
    to a 16 × 56 level; the simulator (one JVM per process, also lazy) plays it ``config.runs``
    times. Building a domain is cheap and the object pickles without the generator or the JVM.

    Args:
        config: The Mario section of a run config.
    """

    name = "mario"
    #: Latents are decoded in float32 anyway, so storing them as float32 loses nothing.
    solution_dtype = np.float32

    def __init__(self, *, config: MarioConfig):
        self.config = config
        self.measure_names = tuple(config.measures)
        self.work_names = tuple(config.work_names)
        unknown = [m for m in self.measure_names if m not in MEASURES]
        if unknown:
            raise ValueError(f"mario.measures: unknown measure(s) {unknown} (known: {sorted(MEASURES)})")
        self.measure_ranges = tuple(tuple(map(float, r)) for r in config.measure_ranges) or tuple(
            NATURAL_RANGES[m] for m in self.measure_names)
        self.archive_dims = tuple(
            d if d > 0 else max(1, int(round(high - low)))
            for d, (low, high) in zip(config.archive_dims, self.measure_ranges))
        self.occupancy_shape = (LEVEL_HEIGHT, LEVEL_WIDTH)
        self.encoding_channels = NUM_TILES
        # one_hot_levels pads to 64×64 itself, on channel 0; the surrogate's padding (none) matches.
        self.encoding_pad_channel = 0
        self._generator = None
        self._simulator = None
        self.solution_dim = 32  # the generator's latent size; checked against the weights on load

    # ------------------------------------------------------------------------------ lazy parts

    @property
    def generator(self):
        """The generator ``config.generator`` names, loaded on first use."""
        if self._generator is None:
            from dsage_ray.domains.mario.generator import load_generator

            generator = load_generator(self.config.generator)
            if generator.latent_dim != self.solution_dim:
                raise ValueError(f"mario.generator: latent size {generator.latent_dim} != {self.solution_dim}")
            self._generator = generator
        return self._generator

    @property
    def simulator(self):
        """The A* simulator for this config (the JVM itself starts on the first episode)."""
        if self._simulator is None:
            from dsage_ray.domains.mario.simulator import MarioSimulator

            self._simulator = MarioSimulator(timer=self.config.timer, astar_iterations=self.config.astar_iterations,
                                             episode_timeout_s=self.config.episode_timeout_s)
        return self._simulator

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_generator"] = None  # torch module: each process loads its own
        state["_simulator"] = None
        return state

    # ---------------------------------------------------------------------------------- levels

    def levels(self, solutions: Solutions) -> np.ndarray:
        """Decodes latents ``(n, 32)`` into ``(n, 16, 56)`` tile-index levels."""
        from dsage_ray.domains.mario.generator import latents_to_levels

        return latents_to_levels(self.generator, np.asarray(solutions, dtype=np.float32).reshape(-1, self.solution_dim))

    def level(self, solution: Solution) -> np.ndarray:
        """The ``(16, 56)`` level one latent decodes to."""
        return self.levels(np.asarray(solution)[None])[0]

    # ---------------------------------------------------------------------------- the protocol

    def random_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """``n`` latents from N(0, ``config.latent_sigma``²) (the authors' 0.2, not the GAN's N(0, 1) prior)."""
        return (self.config.latent_sigma * rng.standard_normal((n, self.solution_dim))).astype(self.solution_dtype)

    def random_valid_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """Every latent decodes to a playable level, so these are :meth:`random_solutions`."""
        return self.random_solutions(n, rng)

    def encode(self, solutions: Solutions) -> EncodedLevels:
        """One-hot ``(n, 17, 64, 64)`` levels, padding on channel 0."""
        return one_hot_levels(self.levels(solutions), size=PADDED_SIZE)

    def level_values(self, encoded: EncodedLevels) -> dict[str, np.ndarray]:
        """What a level fixes by itself, from its encoding (:meth:`encode`): ``sky_tiles``."""
        sky = np.asarray(encoded)[:, EMPTY, :SKY_ROWS, :LEVEL_WIDTH]
        return {"sky_tiles": SKY_ROWS * LEVEL_WIDTH - sky.sum(axis=(1, 2))}

    def run(self, solution: Solution, seed: int = 0) -> MarioEvaluation:
        """The full evaluation of one latent. ``seed`` is unused: the engine has no RNG, and
        with the iteration-count timer the agent is deterministic too."""
        return evaluate_level(self.level(solution), simulator=self.simulator, runs=self.config.runs)

    def evaluate(self, solution: Solution, seed: int) -> EvaluationResult:
        """Objective ``completion`` (mean completion) or ``incompletion`` (1 − it); ``info`` holds the
        evaluation's summary and ``path``, Mario's ``(x, y)`` positions in the first run (for pictures)."""
        result = self.run(solution, seed)
        info = {key: value for key, value in result.to_dict().items() if key != "occupancy"}
        info["path"] = result.episodes[0].path.tolist() if result.episodes else []
        if result.failed:
            failure = EvaluationResult.failure(error=result.error or "evaluation failed",
                                               num_measures=len(self.measure_names),
                                               occupancy_shape=self.occupancy_shape)
            failure.info = info
            return failure
        completion = float(result.objective)
        return EvaluationResult(
            objective=completion if self.config.objective == "completion" else 1.0 - completion,
            measures=np.array([result.measure(m) for m in self.measure_names], dtype=np.float64),
            occupancy=result.occupancy.astype(np.float32),
            info=info,
        )

    def render(self, solution: Solution, occupancy: np.ndarray | None = None, *, path: np.ndarray | None = None,
               title: str | None = None, occupancy_max: float | None = None) -> bytes:
        """PNG of the level a latent decodes to, with the occupancy overlay and Mario's ``path`` when given.

        Args:
            solution: The latent.
            occupancy: Ticks per tile to tint.
            path: ``(ticks, 2)`` positions of Mario in framework pixels, drawn as a line.
            title: A title above the level (with row/column ticks); none: the bare tile image.
            occupancy_max: Top of the tint scale (default: this level's own maximum); one value for a set
                of pictures makes their tints comparable.
        """
        return level_png(self.level(solution), occupancy=occupancy, path=path, title=title,
                         occupancy_max=occupancy_max)

    def level_text(self, solution: Solution) -> str:
        """The level file of a latent (``dsage-ray mario eval --level`` reads it)."""
        return indices_to_string(self.level(solution)) + "\n"

    # ------------------------------------------------------------------------------- audits
    # What the domain-generic audit (dsage_ray.audit) asks of a domain (types.AuditableDomain); the
    # audit's defaults are in the registration (plugin.DOMAIN.audit).

    @classmethod
    def audit_values(cls, *, agent: str, reference: str | None = None, objective: str | None = None,
                     measures: Sequence[str] | None = None) -> dict[str, Any]:
        """The dotted config keys of a Mario audit (:func:`dsage_ray.audit.collection.audit_config`).

        Args:
            agent: ``astar`` or ``astar:ITERATIONS`` (:func:`parse_agent_spec`).
            reference: Must be None: regression audits compare two agents, and Mario has one.
            objective: ``incompletion`` (the default).
            measures: Measure names (default the paper's, the registration's audit measures); one archive cell per
                integer value of each measure's natural range.

        Raises:
            ValueError: An unknown agent, objective or measure, or a reference agent.
        """
        if reference:
            raise ValueError("regression audits (--reference) are Maze-only: the Mario domain has one agent, A*")
        audit = DOMAIN.audit
        objective = objective or audit.objectives[0]
        if objective not in audit.objectives:
            raise ValueError(f"mario audit objective must be one of {', '.join(map(repr, audit.objectives))}, "
                             f"got {objective!r}")
        iterations = parse_agent_spec(agent)
        measures = tuple(measures or audit.measures)
        unknown = [m for m in measures if m not in NATURAL_RANGES]
        if unknown:
            raise ValueError(f"unknown Mario measure(s) {unknown} (known: {sorted(NATURAL_RANGES)})")
        ranges = tuple(NATURAL_RANGES[m] for m in measures)
        values: dict[str, Any] = {
            "mario.objective": objective, "mario.measures": measures, "mario.measure_ranges": ranges,
            "mario.archive_dims": tuple(max(1, int(round(high - low))) for low, high in ranges),
        }
        if iterations is not None:
            values["mario.astar_iterations"] = iterations
        return values

    def preflight(self) -> None:
        """Checks Java, the Mario AI jar and the generator now (without starting a JVM), so a machine
        that cannot play Mario fails in one line before any search.

        Raises:
            ValueError: What is missing.
        """
        from dsage_ray.domains.mario.generator import GeneratorError
        from dsage_ray.domains.mario.simulator import SimulatorError, jar_path

        try:
            import jpype
        except ImportError:
            raise ValueError("mario: JPype is not installed (pip install 'jpype1>=1.5')") from None
        try:
            jpype.getDefaultJVMPath()
            jar_path()
            self.generator
        except jpype.JVMNotFoundException:
            raise ValueError("mario: no Java runtime found (install a JDK 17, or set JAVA_HOME)") from None
        except (SimulatorError, GeneratorError) as exc:
            raise ValueError(f"mario: {exc}") from None

    def play_nominal(self, *, seed: int) -> NominalResult:
        """A* on a flat level (:func:`flat_level`, :class:`~dsage_ray.types.NominalDomain`), ``config.runs`` runs
        (one where the iteration-count timer makes them alike); its return is the completion. ``seed`` is unused,
        as in :meth:`run`.

        Raises:
            ValueError: The runs failed in Java or timed out.
        """
        played = evaluate_level(flat_level(), simulator=self.simulator, runs=self.config.runs)
        if played.failed:
            raise ValueError(f"mario: A* on the flat level failed ({played.error})")
        completion = np.array([episode.completion for episode in played.episodes], dtype=np.float64)
        return NominalResult(
            level=f"a flat level ({LEVEL_WIDTH} columns of ground)", return_name="completion",
            mean_return=float(completion.mean()),
            return_std=float(completion.std(ddof=1)) if len(completion) > 1 else 0.0,
            success_rate=float(np.mean([episode.status == "WIN" for episode in played.episodes])),
            episodes=len(completion), seed=int(seed),
            causes=(f"a game timer too short to cross a level (mario.timer = {self.config.timer} s) or too few A* "
                    f"iterations per tick (mario.astar_iterations = {self.config.astar_iterations})"))

    @property
    def agent_spec(self) -> str:
        return f"astar:{self.config.astar_iterations}"

    @property
    def reference_spec(self) -> None:
        return None

    @property
    def episodes(self) -> int:
        return self.config.runs

    def is_valid(self, solution: Solution) -> bool:
        """Every latent decodes to a playable 16 × 56 level."""
        return True

    def work_counts(self, result: EvaluationResult) -> dict[str, float]:
        """Per run, on average: ``search_iterations``, the A* search iterations spent (what an evaluation's
        time goes on: a stuck Mario searches to the budget every tick), and ``ticks``, the game ticks played."""
        info = result.info
        return {name: float(np.mean(info[name])) if len(info.get(name, ())) else 0.0 for name in self.work_names}

    def success_rate(self, result: EvaluationResult) -> float:
        """The share of the runs that reached the flag."""
        return float(result.info["success_rate"])

    def reference_numbers(self, result: EvaluationResult) -> None:
        """None: Mario audits play one agent (``dsage-ray compare`` plays two, one evaluation each)."""
        return None

    def entry_solution(self, entry: dict[str, Any], folder: Path) -> Solution:
        """The latent a collection entry records, checked to decode to the entry's level file.

        A level file holds tiles, and the latent that decoded to them is not recoverable from it: the
        entry keeps it (``latent``).

        Raises:
            ValueError: An entry without a latent (collections written before they were recorded: rebuild
                the collection with ``dsage-ray audit --collect-only``), or a level file that is not what
                the latent decodes to (edited by hand, or another generator).
        """
        if "latent" not in entry:
            raise ValueError(f"collection level {entry.get('id')}: no recorded latent (collections written before "
                             f"latents were recorded cannot be compared; rebuild it with dsage-ray audit "
                             f"--collect-only)")
        latent = np.asarray(entry["latent"], dtype=self.solution_dtype)
        if latent.shape != (self.solution_dim,):
            raise ValueError(f"collection level {entry.get('id')}: latent of shape {latent.shape}, the generator "
                             f"takes ({self.solution_dim},)")
        path = Path(folder) / entry["level_file"]
        if path.read_text() != self.level_text(latent):
            raise ValueError(f"{path}: not the level the recorded latent decodes to (edited by hand, or another "
                             f"generator than mario.generator={self.config.generator!r})")
        return latent

    def reproduce_command(self, level_file: str | Path, *, seed: int) -> str:
        """The ``dsage-ray mario eval`` command that replays this domain's evaluation of ``level_file``.

        ``seed`` is not part of it: the engine has no randomness, and with the iteration-count timer
        (``astar_iterations > 0``) neither has the agent.
        """
        command = ["dsage-ray", "mario", "eval", "--level", str(level_file), "--runs", str(self.config.runs),
                   "--timer", str(self.config.timer), "--astar-iterations", str(self.config.astar_iterations),
                   "--timeout", f"{self.config.episode_timeout_s:g}"]
        return shlex.join(command)

    def render_evaluation(self, solution: Solution, result: EvaluationResult, *, title: str | None = None,
                          occupancy_max: float | None = None) -> bytes:
        """The level with Mario's occupancy and the path of the first run from ``result``."""
        path = np.asarray(result.info.get("path") or np.zeros((0, 2)), dtype=np.float64).reshape(-1, 2)
        return self.render(solution, result.occupancy, path=path, title=title, occupancy_max=occupancy_max)

    def collection_fields(self) -> dict[str, Any]:
        """Mario settings at the top level of a collection (beside the generic keys)."""
        return {"timer": self.config.timer, "astar_iterations": self.config.astar_iterations}

    def entry_fields(self, solution: Solution, result: EvaluationResult, *, level_file: str) -> dict[str, Any]:
        """The Mario numbers of a collection entry beside the generic ones."""
        info = result.info
        completion = [float(c) for c in info["completion"]]
        return {
            "completion": float(np.mean(completion)),
            "completion_per_run": completion,
            "jumps": float(info["mean_jumps"]),
            "kills": float(info["enemies_killed"]),
            "sky_tiles": int(info["sky_tiles"]),
            "status": list(info["status"]),
            "ticks": [int(t) for t in info["ticks"]],
            # The level file holds tiles only; compare re-runs the latent (entry_solution).
            "latent": [float(x) for x in np.asarray(solution, dtype=np.float32)],
        }
