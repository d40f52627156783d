# Two commands on a fresh machine:
#   make demo   installs into .venv if needed, then runs the main job
#   make test   installs into .venv if needed, then runs the test suite
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: install demo test bench clean

$(STAMP): requirements.txt lhd_loading_ros/setup.py lhd_sim_node/setup.py lhd_hw_bridge/setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt
	$(PY) -m pip install -q --no-deps --config-settings editable_mode=compat -e lhd_loading_ros -e lhd_sim_node -e lhd_hw_bridge
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/lhd demo

test: $(STAMP)
	$(PY) -m pytest -q test

bench: $(STAMP)
	$(VENV)/bin/lhd bench sim --json

clean:
	rm -rf $(VENV) build install log .pytest_cache
