"""The Mario domain behind the :class:`~dsage_ray.types.Domain` protocol (SPEC §3)."""

from __future__ import annotations

from typing import Any

import numpy as np

from dsage_ray.config import MarioConfig
from dsage_ray.domains.mario.encoding import PADDED_SIZE, one_hot_levels
from dsage_ray.domains.mario.evaluate import MEASURES, MarioEvaluation, evaluate_level
from dsage_ray.domains.mario.render import level_png
from dsage_ray.domains.mario.tiles import LEVEL_HEIGHT, LEVEL_WIDTH, NUM_TILES, indices_to_string
from dsage_ray.types import EncodedLevels, EvaluationResult, Solution, Solutions

#: Natural range of each measure, used when the config gives no ``measure_ranges``.
#: Sky tiles and jumps follow the paper; kills follow its appendix ([0, 25]).
NATURAL_RANGES: dict[str, tuple[float, float]] = {
    "sky_tiles": (0.0, 150.0),
    "mean_jumps": (0.0, 100.0),
    "enemies_killed": (0.0, 25.0),
}


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

    def encode(self, solutions: Solutions) -> EncodedLevels:
        """One-hot ``(n, 17, 64, 64)`` levels, padding on channel 0."""
        return one_hot_levels(self.levels(solutions), size=PADDED_SIZE)

    def run(self, solution: Solution, seed: int = 0) -> MarioEvaluation:
        """The full evaluation of one latent. ``seed`` is unused: the engine has no RNG, and
        with the iteration-count timer the agent is deterministic too."""
        return evaluate_level(self.level(solution), simulator=self.simulator, runs=self.config.runs)

    def evaluate(self, solution: Solution, seed: int) -> EvaluationResult:
        result = self.run(solution, seed)
        info = {key: value for key, value in result.to_dict().items() if key != "occupancy"}
        if result.failed:
            failure = EvaluationResult.failure(error=result.error or "evaluation failed",
                                               num_measures=len(self.measure_names),
                                               occupancy_shape=self.occupancy_shape)
            failure.info = info
            return failure
        return EvaluationResult(
            objective=float(result.objective),
            measures=np.array([result.measure(m) for m in self.measure_names], dtype=np.float64),
            occupancy=result.occupancy.astype(np.float32),
            info=info,
        )

    def render(self, solution: Solution, occupancy: np.ndarray | None = None) -> bytes:
        """PNG of the level a latent decodes to, with the occupancy overlay when given."""
        return level_png(self.level(solution), occupancy=occupancy)

    def level_text(self, solution: Solution) -> str:
        return indices_to_string(self.level(solution))
