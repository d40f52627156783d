# Two commands on a fresh machine:
#   make demo   installs into .venv if needed, then runs the main job
#   make test   installs into .venv if needed, then runs the default test suite
# (make test-stack: the end-to-end stacks, which CI runs as well)
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

# Where PYTHONDONTWRITEBYTECODE is set (this project's machines set it), nothing caches compiled
# modules: every pytest process rewrote the asserts of all 119 test modules again (20 s of collection
# instead of 7.5 s, in each xdist worker of each pass), and every node process compiled the
# project's own modules again. The commands make runs write their __pycache__ (git ignores it).
unexport PYTHONDONTWRITEBYTECODE

COLCON_VENV := .venv-colcon
COLCON_STAMP := $(COLCON_VENV)/.installed

.PHONY: install demo test test-stack bench clean colcon-build

# pip byte-compiles at install (not --no-compile): where PYTHONDONTWRITEBYTECODE is set, as on
# this project's machines, nothing would cache the .pyc later and every node process would compile
# torch & co. again (the node pass took 708 s instead of 524 s)
$(STAMP): requirements.txt lhd_loading_ros/setup.py lhd_sim_node/setup.py lhd_hw_bridge/setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt
	$(PY) -m pip install -q --no-deps --config-settings editable_mode=compat -e lhd_loading_ros -e lhd_sim_node -e lhd_hw_bridge
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/lhd demo

# colcon-common-extensions lives in its own venv: it is a build tool, not a runtime dependency
$(COLCON_STAMP):
	test -x $(COLCON_VENV)/bin/python || $(PYTHON) -m venv $(COLCON_VENV)
	$(COLCON_VENV)/bin/python -m pip install -q colcon-common-extensions==0.3.0
	touch $(COLCON_STAMP)

# what a user with a full ROS install does: colcon build of the three ament_python packages
colcon-build: $(COLCON_STAMP)
	rm -rf build install log
	$(COLCON_VENV)/bin/colcon --log-base log build --base-paths lhd_loading_ros lhd_sim_node lhd_hw_bridge \
		--build-base build --install-base install --event-handlers console_cohesion- summary+

# The default suite, `make test`, in two passes. Tests of the pure core (simulator, task math,
# learning, perception on arrays; no node processes, no DDS) run on CPU_JOBS pytest-xdist workers.
# Tests that start node processes or talk over DDS (marked `ros` by test/conftest.py) run on
# TEST_JOBS workers, one test file per worker (each worker has its own DDS domain, test/rosutil.py).
# `make test-stack` runs the tests of whole stacks and pipelines end to end (the twin, `lhd up sim`,
# `lhd up real`, `lhd bench twin`, sensor streams at their rates, training over ROS, a Ray sweep;
# marked `serial` by a module-level SERIAL = True), alone: two of them on two workers of a 2-core
# machine starved each other (2 of 5 runs failed). CI (.ci/run) runs both. TEST_JOBS=1 runs every
# process test serially.
CPU_JOBS ?= 2
TEST_JOBS ?= 2
XDIST := $(if $(filter-out 1,$(TEST_JOBS)),-n $(TEST_JOBS) --dist loadfile,)
CPU_XDIST := $(if $(filter-out 1,$(CPU_JOBS)),-n $(CPU_JOBS) --dist load,)
# every pass runs even when the one before it failed; make test fails when any did
test: $(STAMP) colcon-build
	@status=0; \
	$(PY) -m pytest -q --durations=10 -m "not ros" $(CPU_XDIST) test || status=1; \
	$(PY) -m pytest -q --durations=15 -m "ros and not serial" $(XDIST) test || status=1; \
	exit $$status

test-stack: $(STAMP)
	$(PY) -m pytest -q --durations=10 -m "ros and serial" test

bench: $(STAMP)
	$(VENV)/bin/lhd bench sim --json

clean:
	rm -rf $(VENV) $(COLCON_VENV) build install log .pytest_cache
