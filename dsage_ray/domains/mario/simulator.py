"""The Mario AI framework and Robin Baumgarten's A* agent, in-process through JPype.

One JVM per process, started lazily on first use (headless; classpath = the ``mario-gpt``
wheel's ``PlayAstar.jar`` plus our compiled :file:`java/DeterministicTimer.java`). The game loop
is Python, calling the framework's public classes exactly as ``MarioGame.gameLoop`` does (this
build has no ``runGame``, and its ``playAstar`` sleeps to 30 fps):

1. ``world = new MarioWorld(null, 1)``; ``world.initializeLevel(level, 1000·timer)``; set
   Mario's size; one ``world.update`` with no buttons pressed.
2. ``agent.initialize(new MarioForwardModel(world.clone()), timer)``.
3. While ``world.gameStatus == RUNNING``: a fresh timer per tick,
   ``actions = agent.getActions(new MarioForwardModel(world.clone()), timer)``,
   ``world.update(actions)``, collect ``world.lastFrameEvents`` and a ``MarioAgentEvent``.
4. ``new MarioResult(world, gameEvents, agentEvents)``.

The stock timer gives the agent 40 ms of wall clock per tick, so results depend on machine
load (SPEC: Mario). With ``astar_iterations > 0`` the timer is our ``DeterministicTimer``, which
counts A* search iterations instead, making an episode a pure function of the level.
"""

from __future__ import annotations

import dataclasses
import faulthandler
import gc
import hashlib
import logging
import os
import shutil
import subprocess
import tempfile
import threading
import time
import warnings
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.domains.mario.human_levels import MarioDataError, mario_gpt_file
from dsage_ray.domains.mario.tiles import to_string
from dsage_ray.errors import ResourceError

logger = logging.getLogger(__name__)

JAVA_SOURCE = Path(__file__).parent / "java" / "DeterministicTimer.java"
TIMER_CLASS = "dsagemario.DeterministicTimer"
#: Overrides the folder compiled Java classes are cached in.
CACHE_ENV = "DSAGE_RAY_JAVA_CACHE"
#: Extra JVM options, whitespace-separated (e.g. ``-Xmx2g``).
JVM_OPTS_ENV = "DSAGE_RAY_JVM_OPTS"
#: Wall-clock budget of the stock timer per agent call, as in the framework's own loop.
STOCK_TIMER_MS = 40
#: Game time per tick in ms (the framework's fixed 30 fps step).
TICK_MS = 30

#: Episode statuses besides the framework's WIN / LOSE / TIME_OUT.
WALL_CLOCK_TIMEOUT = "WALL_CLOCK_TIMEOUT"
JAVA_ERROR = "ERROR"


class SimulatorError(ResourceError):
    """Java, the jar, or the JVM is unusable (not an individual episode's failure)."""


def jar_path() -> Path:
    """Location of ``PlayAstar.jar`` inside the installed ``mario-gpt`` distribution."""
    try:
        return mario_gpt_file("mario_gpt/simulator/PlayAstar.jar")
    except MarioDataError as exc:
        raise SimulatorError(str(exc)) from None


# ----------------------------------------------------------------------------- Java compilation

def _cache_root() -> Path:
    env = os.environ.get(CACHE_ENV)
    return Path(env) if env else Path.home() / ".cache" / "dsage_ray" / "java"


def compile_timer_class(*, jar: Path | None = None, javac: str | None = None) -> Path | None:
    """Compiles :data:`JAVA_SOURCE` once and returns its class folder, or ``None`` without ``javac``.

    The folder name hashes the source, the jar and the ``javac`` binary, so any change recompiles.
    Compilation goes to a temporary folder that is renamed into place, so concurrent processes
    (Ray actors starting together) never see a half-written class.

    Raises:
        SimulatorError: If ``javac`` exists but fails.
    """
    javac = javac or shutil.which("javac")
    if javac is None:
        return None
    jar = jar or jar_path()
    javac_real = Path(javac).resolve()
    key = hashlib.sha256()
    key.update(JAVA_SOURCE.read_bytes())
    key.update(hashlib.sha256(jar.read_bytes()).digest())
    key.update(f"{javac_real}:{javac_real.stat().st_mtime_ns}".encode())
    target = _cache_root() / key.hexdigest()[:16]
    if (target / "dsagemario" / "DeterministicTimer.class").is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".compile-", dir=target.parent))
    try:
        proc = subprocess.run([javac, "-nowarn", "-cp", str(jar), "-d", str(tmp), str(JAVA_SOURCE)],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            raise SimulatorError(f"javac failed on {JAVA_SOURCE.name}: {proc.stderr.strip()}")
        try:
            os.rename(tmp, target)
        except OSError:
            # Another process won the race; its folder is identical.
            if not (target / "dsagemario" / "DeterministicTimer.class").is_file():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return target


# ---------------------------------------------------------------------------------------- JVM

@dataclasses.dataclass(frozen=True)
class _Java:
    """Handles to the Java classes the game loop uses (resolved once per process)."""

    MarioWorld: Any
    MarioForwardModel: Any
    MarioAgentEvent: Any
    MarioResult: Any
    MarioTimer: Any
    DeterministicTimer: Any | None
    Agent: Any
    ArrayList: Any
    GameStatus: Any
    JBooleanArray: Any
    JException: Any
    num_actions: int
    jvm_start_s: float


_java: _Java | None = None
_java_lock = threading.Lock()
_warned_stock_timer = False


def signal_chaining_library() -> str | None:
    """The JDK's ``libjsig.so``, or None.

    Preloaded (``LD_PRELOAD``), it lets the JVM chain its SIGSEGV handler with handlers that Python
    code installs later; without it a JIT implicit null check in the A* search occasionally reached
    another handler and aborted the process (seen under pytest: ~1 run in 4; 0 in 8 with it).
    """
    try:
        import jpype

        libjvm = Path(jpype.getDefaultJVMPath())
    except Exception:  # noqa: BLE001 - no JPype or no Java: nothing to chain
        return None
    for candidate in (libjvm.parent.parent / "libjsig.so", libjvm.parent / "libjsig.so"):
        if candidate.exists():
            return str(candidate)
    return None


def java() -> _Java:
    """Starts the JVM on first call (thread-safe) and returns the framework classes."""
    global _java
    if _java is not None:
        return _java
    with _java_lock:
        if _java is None:
            _java = _start_jvm()
    return _java


def _keep_faulthandler_off() -> None:
    """Turns Python's faulthandler off; called before the JVM starts and before every episode.

    The JVM raises SIGSEGV on purpose (implicit null checks in JIT-compiled code). With Python's
    faulthandler installed (pytest and Ray turn it on) such a signal reaches faulthandler, which
    kills the process at random (JPype user guide, "JIT and faulthandler"; we saw it in
    ``AStarTree.pickBestPos``). Disabling restores the handler faulthandler displaced, so this is
    also the fix when something re-enables it after the JVM started.
    """
    if faulthandler.is_enabled():
        faulthandler.disable()
        logger.info("Python faulthandler disabled: it conflicts with the JVM's signal handling")


def _unlink_garbage_collectors() -> None:
    """Stops JPype from running Java's garbage collector along with Python's.

    JPype registers a callback on every Python collection (``gc.callbacks``) that, once the process's Python memory
    passes its marks, asks the JVM for a collection too (jpype-project/jpype#1197). In a DSAGE run on Mario that kept
    JPype's "Python Reference Queue" thread busy for more than half of a core, taken from the episodes
    (``benchmarks/bench_mario_gc.py``). The link exists for reference cycles between Python and Java objects; an
    episode makes none (Python holds Java objects only, released when their Python handles go), and each collector
    still runs on its own heap's pressure.
    """
    import _jpype

    collect = getattr(_jpype, "_collect", None)
    while collect is not None and collect in gc.callbacks:
        gc.callbacks.remove(collect)


def _start_jvm() -> _Java:
    try:
        import jpype
        import jpype.imports  # noqa: F401  (enables Java packages as modules)
    except ImportError:
        raise SimulatorError("JPype is not installed (pip install 'jpype1>=1.5')") from None
    jar = jar_path()
    try:
        classes = compile_timer_class(jar=jar)
    except (OSError, subprocess.SubprocessError) as exc:
        raise SimulatorError(f"cannot compile {JAVA_SOURCE.name}: {exc}") from None
    start = time.perf_counter()
    if jpype.isJVMStarted():
        # Someone else started the JVM: we can only use it if our jar is on its classpath.
        try:
            jpype.JClass("engine.core.MarioWorld")
        except Exception:
            raise SimulatorError("a JVM is already running in this process without the Mario jar on its "
                                 "classpath; JPype cannot restart it") from None
    else:
        classpath = [str(jar)] + ([str(classes)] if classes else [])
        try:
            jvm = jpype.getDefaultJVMPath()
        except jpype.JVMNotFoundException:
            raise SimulatorError("no Java runtime found (install a JDK 17, or set JAVA_HOME)") from None
        # Crash reports go to the temp folder, not the working directory (often a git checkout).
        error_file = Path(tempfile.gettempdir()) / "dsage_ray_hs_err_pid%p.log"
        opts = ["-Djava.awt.headless=true", f"-XX:ErrorFile={error_file}", *os.environ.get(JVM_OPTS_ENV, "").split()]
        _keep_faulthandler_off()
        chaining = signal_chaining_library()
        if chaining and chaining not in os.environ.get("LD_PRELOAD", ""):
            warnings.warn(f"the JVM runs without signal chaining; Python libraries that install signal handlers "
                          f"(faulthandler in pytest and Ray workers) can crash it at random. Start the process "
                          f"with LD_PRELOAD={chaining} (the Makefile and the Ray pool do).", RuntimeWarning, stacklevel=2)
        jpype.startJVM(jvm, *opts, classpath=classpath, convertStrings=False)
        _unlink_garbage_collectors()
    jvm_start_s = time.perf_counter() - start
    JClass = jpype.JClass
    try:
        timer_cls = JClass(TIMER_CLASS) if classes else None
    except Exception:
        timer_cls = None  # JVM started elsewhere without our class folder; fall back below.
    handles = _Java(
        MarioWorld=JClass("engine.core.MarioWorld"),
        MarioForwardModel=JClass("engine.core.MarioForwardModel"),
        MarioAgentEvent=JClass("engine.core.MarioAgentEvent"),
        MarioResult=JClass("engine.core.MarioResult"),
        MarioTimer=JClass("engine.core.MarioTimer"),
        DeterministicTimer=timer_cls,
        Agent=JClass("agents.robinBaumgarten.Agent"),
        ArrayList=JClass("java.util.ArrayList"),
        GameStatus=JClass("engine.helper.GameStatus"),
        JBooleanArray=jpype.JArray(jpype.JBoolean),
        JException=jpype.JException,
        num_actions=int(JClass("engine.helper.MarioActions").numberOfActions()),
        jvm_start_s=jvm_start_s,
    )
    logger.info("JVM ready in %.2f s (deterministic timer: %s)", jvm_start_s, timer_cls is not None)
    return handles


def jvm_start_seconds() -> float:
    """Seconds the JVM start took in this process (0 if it was already running)."""
    return java().jvm_start_s


# ------------------------------------------------------------------------------------ episodes

@dataclasses.dataclass
class EpisodeResult:
    """One A* playthrough of one level.

    Attributes:
        status: ``WIN``, ``LOSE``, ``TIME_OUT`` (game timer), ``WALL_CLOCK_TIMEOUT`` or ``ERROR``.
        completion: ``MarioResult.getCompletionPercentage()``: Mario's x over the exit's x.
        jumps: ``getNumJumps()``.
        kills: ``getKillsTotal()``.
        ticks: Game ticks played.
        path: ``(ticks, 2)`` float32 Mario positions ``(x, y)`` in pixels after each tick
            (16 px per tile, ``y`` at Mario's feet), as in ``MarioAgentEvent``.
        wall_s: Wall-clock seconds the episode took.
        deterministic: Whether the iteration-count timer was used.
        error: The Java or timeout message when ``status`` is ``ERROR`` / ``WALL_CLOCK_TIMEOUT``.
        extra: Other ``MarioResult`` counters (coins, lives, stomps, ...).
        search_iterations: A* search iterations the agent spent over the episode (with the iteration-count
            timer; 0 with the stock one). With the ticks, what the episode cost, as a count that does not
            depend on the machine.
    """

    status: str
    completion: float
    jumps: int
    kills: int
    ticks: int
    path: np.ndarray
    wall_s: float
    deterministic: bool
    error: str | None = None
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)
    search_iterations: int = 0

    @property
    def ok(self) -> bool:
        return self.status not in (WALL_CLOCK_TIMEOUT, JAVA_ERROR)


class MarioSimulator:
    """Plays levels with the A* agent.

    Args:
        timer: Game time in seconds (20 → 666 ticks at 30 ms each).
        astar_iterations: A* search iterations per tick; ``0`` uses the stock 40 ms wall-clock
            timer (load-dependent, as the framework ships).
        mario_state: 0 small, 1 large, 2 fire Mario at the start.
        episode_timeout_s: Wall-clock limit per episode; past it the episode stops with status
            ``WALL_CLOCK_TIMEOUT`` so a pathological level cannot hang a worker.
    """

    def __init__(self, *, timer: int = 20, astar_iterations: int = 1000, mario_state: int = 0,
                 episode_timeout_s: float = 60.0) -> None:
        if timer < 1:
            raise ValueError(f"timer must be positive, got {timer}")
        if astar_iterations < 0:
            raise ValueError(f"astar_iterations must be >= 0, got {astar_iterations}")
        if mario_state not in (0, 1, 2):
            raise ValueError(f"mario_state must be 0 (small), 1 (large) or 2 (fire), got {mario_state}")
        if episode_timeout_s <= 0:
            raise ValueError(f"episode_timeout_s must be positive, got {episode_timeout_s}")
        self.timer = timer
        self.astar_iterations = astar_iterations
        self.mario_state = mario_state
        self.episode_timeout_s = episode_timeout_s

    @property
    def deterministic(self) -> bool:
        """True when episodes use the iteration-count timer (needs ``javac``; starts the JVM)."""
        return self.astar_iterations > 0 and java().DeterministicTimer is not None

    def _timer_factory(self, j: _Java):
        global _warned_stock_timer
        if self.astar_iterations > 0:
            if j.DeterministicTimer is not None:
                budget = self.astar_iterations
                return lambda: j.DeterministicTimer(budget)
            if not _warned_stock_timer:
                _warned_stock_timer = True
                warnings.warn("javac is not available: Mario evaluations use the stock 40 ms wall-clock A* "
                              "timer, so results depend on machine load", RuntimeWarning, stacklevel=3)
        return lambda: j.MarioTimer(STOCK_TIMER_MS)

    def play(self, level: np.ndarray | str | Sequence[str]) -> EpisodeResult:
        """Plays one episode.

        Raises:
            LevelError: If the level is invalid (checked before anything reaches Java).
            SimulatorError: If the JVM or jar cannot be used.
        """
        text = to_string(level)
        j = java()
        _keep_faulthandler_off()
        make_timer = self._timer_factory(j)
        deterministic = self.astar_iterations > 0 and j.DeterministicTimer is not None
        start = time.perf_counter()
        deadline = start + self.episode_timeout_s
        path: list[tuple[float, float]] = []
        searched = 0

        def unfinished(status: str, error: str) -> EpisodeResult:
            # An episode that did not reach a game end has no completion; the evaluation fails.
            return EpisodeResult(status=status, completion=float("nan"), jumps=0, kills=0, ticks=len(path),
                                 path=np.asarray(path, dtype=np.float32).reshape(-1, 2),
                                 wall_s=time.perf_counter() - start, deterministic=deterministic, error=error,
                                 search_iterations=searched)

        try:
            world = j.MarioWorld(None, 1)
            world.visuals = False
            world.initializeLevel(text, 1000 * self.timer)
            world.mario.isLarge = self.mario_state > 0
            world.mario.isFire = self.mario_state > 1
            world.update(j.JBooleanArray(j.num_actions))
            agent = j.Agent()
            agent.initialize(j.MarioForwardModel(world.clone()), make_timer())
            game_events = j.ArrayList()
            agent_events = j.ArrayList()
            running = j.GameStatus.RUNNING
            while world.gameStatus == running:
                if time.perf_counter() > deadline:
                    return unfinished(WALL_CLOCK_TIMEOUT, f"episode exceeded {self.episode_timeout_s:g} s of "
                                                          f"wall clock after {len(path)} ticks")
                timer = make_timer()
                actions = agent.getActions(j.MarioForwardModel(world.clone()), timer)
                if deterministic:
                    # The timer is thrown away after the tick, so reading (and spending) what is left is free.
                    searched += self.astar_iterations - int(timer.getRemainingTime())
                world.update(actions)
                game_events.addAll(world.lastFrameEvents)
                mario = world.mario
                x, y = float(mario.x), float(mario.y)
                agent_events.add(j.MarioAgentEvent(actions, x, y, int(bool(mario.isLarge)) + int(bool(mario.isFire)),
                                                   mario.onGround, world.currentTick))
                path.append((x, y))
            result = j.MarioResult(world, game_events, agent_events)
            return EpisodeResult(
                status=str(result.getGameStatus().toString()),
                completion=float(result.getCompletionPercentage()),
                jumps=int(result.getNumJumps()),
                kills=int(result.getKillsTotal()),
                ticks=len(path),
                path=np.asarray(path, dtype=np.float32).reshape(-1, 2),
                wall_s=time.perf_counter() - start,
                deterministic=deterministic,
                search_iterations=searched,
                extra={
                    "coins": int(result.getCurrentCoins()),
                    "lives": int(result.getCurrentLives()),
                    "mario_mode": int(result.getMarioMode()),
                    "stomps": int(result.getKillsByStomp()),
                    "remaining_time_ms": int(result.getRemainingTime()),
                },
            )
        except j.JException as exc:
            return unfinished(JAVA_ERROR, f"{exc.getClass().getName()}: {exc.getMessage()}")
