# Two commands on a fresh machine:  `make run`  (a real DSAGE run)  and  `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: venv run test test-slow bench bench-run clean

# Benchmarks that read a finished run (RUN=its folder, holding checkpoint.dsage) instead of making their own data.
RUN_BENCHMARKS := benchmarks/bench_surrogate_training.py benchmarks/bench_surrogate_ceiling.py
# Benchmarks that read the run folders of a published experiment (their commands are in docs/results).
FOLDER_BENCHMARKS := benchmarks/bench_equal_compute.py benchmarks/bench_evaluation_cost.py

$(STAMP): pyproject.toml Makefile
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/pip install --upgrade --quiet pip
	# torch first: the pinned CPU build is on disk; an unpinned torch would pull a multi-GB CUDA build.
	$(BIN)/pip install --quiet torch==2.13.0
	# An old egg-info at the root would shadow the installed metadata, and with it the domain entry points.
	rm -rf dsage_ray.egg-info
	$(BIN)/pip install --quiet -e '.[mario,dev,bench,gym,sb3,sb3_contrib]'
	# mario-gpt ships the Mario AI jar and the human levels; its own deps (transformers) are not needed.
	$(BIN)/pip install --quiet --no-deps mario-gpt==0.1.3
	touch $(STAMP)

venv: $(STAMP)

run: $(STAMP)
	# The main job: audit the shipped PPO agent with DSAGE (through Ray Tune) and write a collection.
	$(BIN)/dsage-ray audit --agent rllib:ppo_maze --preset demo --budget 300 --out tb_logs/audit_ppo_maze_$$(date +%Y%m%d-%H%M%S)

# The JDK's libjsig.so lets the in-process JVM (Mario) chain signal handlers with Python's.
JSIG := $(shell j=$$(readlink -f $$(command -v java) 2>/dev/null) && ls $$(dirname $$(dirname $$j))/lib/libjsig.so 2>/dev/null)

# Two pytest workers, each taking whole files (module fixtures are built once) and starting its own 2-CPU Ray
# cluster: most of the suite waits on process start-up, so 2 workers on 2 cores took 737 s against 1,141 s for one
# (measured). --no-loadscope-reorder: files go out in collection order, which tests/conftest.py begins with the
# slowest (xdist would hand them out by test count, the one-test Tune files last, one worker alone with them).
# --durations: every CI log lists the slowest tests, to keep the suite under its 10 minutes.
# compileall first: where the environment forbids writing bytecode (PYTHONDONTWRITEBYTECODE, set on the development
# machine), every process the suite starts (Tune trials, actors, command runs) would compile the package's sources
# again: 0.2-0.5 s of CPU a process on the package's imports, measured (pip compiled the installed libraries).
# The Maze's numba kernels likewise: on a clean clone each process that evaluated a maze before one had written the
# kernel cache compiled them (about 4 s each; tests/audit/test_audit.py alone took 14 s longer, measured).
test: $(STAMP)
	$(BIN)/python -m compileall -q -j 0 dsage_ray tests examples > /dev/null
	$(BIN)/python -c "from dsage_ray.domains.maze.paths import compile_kernels; compile_kernels()"
	RAY_AUTH_MODE=disabled LD_PRELOAD=$(JSIG) $(BIN)/python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder --durations=20

# The long tests the default suite leaves out (marked slow: end-to-end script runs and long checks whose parts the
# default suite covers, runs of the real ACCEL agent, and the 4-node cluster); about 7 minutes on 2 cores (17 tests
# in about 440 s: the sum of their measured durations, the 8 earlier ones' 158 s, 23 + 16 + 37 + 38 + 29 s for the
# five added by issue 63, 79 s for the three mode-equality cases beside DSAGE's pipelined one, and 60 s for Mario
# through Tune).
test-slow: $(STAMP)
	RAY_AUTH_MODE=disabled LD_PRELOAD=$(JSIG) $(BIN)/python -m pytest -q -m slow

bench: $(STAMP)
	for b in $(filter-out $(RUN_BENCHMARKS) $(FOLDER_BENCHMARKS),$(wildcard benchmarks/bench_*.py)); do $(BIN)/python $$b || exit 1; done

# e.g. make bench-run RUN=tb_logs/maze_dsage   (a Maze surrogate run with held-out levels)
bench-run: $(STAMP)
	@test -n "$(RUN)" || { echo "bench-run: set RUN=<a finished Maze run folder>"; exit 2; }
	for b in $(RUN_BENCHMARKS); do $(BIN)/python $$b $(RUN) || exit 1; done

clean:
	rm -rf $(VENV)
