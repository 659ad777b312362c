# One command per job; each installs what is missing first.
#   make demo    install, then run the main job on the built-in defaults: a synthetic dataset, verify, the report
#   make verify DATASET=folder SCENE=scene [RUN=out/verify] [SCHEDULER=tcp://host:8786 | WORKERS=N] photos to report in one
#                resumable run; with SCHEDULER, its tasks (tables, each photo's calibration, the fit, render passes,
#                reports) run on that dask.distributed cluster
#   make paper   verify with the paper's settings (paper tables, the targeted render, the paper's 978 x 734 frame)
#   make check   lint (ruff), types (mypy), configured in pyproject.toml, and the layering (tests/check_layering.py)
#   make test    the whole test suite on TEST_WORKERS pytest-xdist workers (default 2; `make test-fast` skips the slow
#                marker, `make test-heavy` runs the whole-run checks it leaves out)
#   make bench   benchmarks: the solver against open-source peers (separate env .venv-bench), tables, renders, calibration, reports, the planner

PYTHON ?= python3
TEST_WORKERS ?= 2
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# The editable install maps each module to its file (scikit-build-core's redirect mode): when modules
# are added, moved or removed, the map must be rebuilt, so the list of modules is a prerequisite too
# (rewritten only when it changes).
MODULE_LIST := $(VENV)/.module-list
$(shell mkdir -p $(VENV) && find rcwa renderer calibration datasets_synthetic reports workbench -name '*.py' \
  -not -path '*/__pycache__/*' | LC_ALL=C sort > $(MODULE_LIST).new && \
  { cmp -s $(MODULE_LIST).new $(MODULE_LIST) && rm $(MODULE_LIST).new || mv $(MODULE_LIST).new $(MODULE_LIST); })
SOURCES := pyproject.toml CMakeLists.txt $(wildcard rcwa/cpp/*.cpp rcwa/cpp/*.hpp) $(MODULE_LIST)

.PHONY: install demo verify paper check test test-fast test-heavy bench clean

install: $(STAMP)

# The venv, the build tools (no build isolation, so rebuilds reuse them) and the package
# in editable mode: Python edits take effect at once, C++ edits rebuild through this rule.
$(STAMP): $(SOURCES)
	@command -v c++ >/dev/null || { echo "installing g++ (Debian)"; apt-get update -q && apt-get install -y -q g++; }
	@# Mitsuba's LLVM backend needs libLLVM 19 (drjit 1.5 crashes with Debian's default 15).
	@ls /usr/lib/*/libLLVM-19.so* >/dev/null 2>&1 || { echo "installing libllvm19 (Debian)"; \
	  (apt-get update -q && apt-get install -y -q libllvm19) || echo "warning: libllvm19 not installed; rendering will use the scalar variant"; }
	@# The report page's browser test drives Debian's chromium (Playwright's own browser download is not available).
	@command -v chromium >/dev/null || { echo "installing chromium (Debian)"; \
	  (apt-get update -q && apt-get install -y -q chromium) || echo "warning: chromium not installed; the report page's browser test will fail"; }
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q "scikit-build-core>=0.10" "nanobind>=2.4" "scipy-openblas32>=0.3.28" cmake ninja
	@# opencv-contrib-python-headless replaces opencv-python-headless (both install cv2, and removing either
	@# later breaks the other): a venv that still has the old one drops both, and the next line installs contrib.
	@if $(BIN)/python -m pip show -q opencv-python-headless >/dev/null 2>&1; then \
	  $(BIN)/python -m pip uninstall -y -q opencv-python-headless opencv-contrib-python-headless; fi
	$(BIN)/python -m pip install -q --no-build-isolation -e '.[test]'
	@touch $@

demo: install
	$(BIN)/workbench demo

# verify: any dataset folder (photos/, and optionally brackets/ and calibration/) against a scene.
# Stages already finished in RUN with the same inputs are skipped; a killed run resumes.
# SCHEDULER: the address of a running dask scheduler (docs/architecture.md, "verify on a cluster").
SCENE ?= cornell_cd
RUN ?= out/verify
VERIFY_ARGS ?=
SCHEDULER ?=
WORKERS ?=
verify: install
	@test -n "$(DATASET)" || { echo "usage: make verify DATASET=folder [SCENE=$(SCENE)] [RUN=$(RUN)] [SCHEDULER=tcp://host:8786] [VERIFY_ARGS='--spp 64 ...']"; exit 2; }
	$(BIN)/workbench verify $(DATASET) --scene $(SCENE) --out $(RUN) $(if $(SCHEDULER),--scheduler $(SCHEDULER)) $(if $(WORKERS),--workers $(WORKERS)) $(VERIFY_ARGS)

# paper: the paper's settings (DESIGN.md; Lange et al. 2021, Fig. 4): paper-preset tables (31 wavelengths, 2 deg
# steps), a targeted render (the frame capped at 2045 spp), at the photos' size. Without DATASET, the full
# synthetic dataset of SCENE at the paper's 978 x 734 frame is made first (out/paper/dataset, about 15 minutes;
# once); the run goes to out/paper/run.
# Each photo's targeted render (the CD's edges to 0.1 px) took 102 s on a quiet 2-core machine, one photo's whole
# verify about 3.5 minutes with the tables cached (more when the fit re-renders); the fixed VERIFY_ARGS='--spp 2045'
# about half an hour (VERIFY_ARGS='--photo view0.dng' renders one).
PAPER_DATASET ?= out/paper/dataset
paper: install
	@if [ -z "$(DATASET)" ] && [ ! -f $(PAPER_DATASET)/truth.json ]; then \
	  $(BIN)/workbench synth $(SCENE) --out $(PAPER_DATASET) --preset full; fi
	$(BIN)/workbench verify $(or $(DATASET),$(PAPER_DATASET)) --scene $(SCENE) --out out/paper/run --preset paper $(VERIFY_ARGS)
	@if [ -z "$(DATASET)" ]; then $(BIN)/workbench score out/paper/run --truth $(PAPER_DATASET)/truth.json; fi

check: install
	$(BIN)/ruff check .
	$(BIN)/mypy
	$(BIN)/python -m tests.check_layering

test: install
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile -m "not heavy" --durations=30

test-fast: install
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile -m "not slow and not heavy"

test-heavy: install
	$(BIN)/python -m pytest -q -m heavy

bench: install
	bash benchmarks/setup_peers.sh
	$(BIN)/python benchmarks/bench_solve.py
	$(BIN)/python -m benchmarks.bench_convergence
	$(BIN)/python -m benchmarks.bench_table
	$(BIN)/python -m benchmarks.bench_bwdf
	$(BIN)/python -m benchmarks.bench_noise
	$(BIN)/python -m benchmarks.bench_fit
	$(BIN)/python -m benchmarks.bench_render
	$(BIN)/python -m benchmarks.bench_corners
	$(BIN)/python -m benchmarks.bench_lens_terms
	$(BIN)/python -m benchmarks.bench_calibration
	$(BIN)/python -m benchmarks.bench_report
	$(BIN)/python -m benchmarks.bench_large_photo
	$(BIN)/python -m benchmarks.bench_plan
	$(BIN)/python -m benchmarks.bench_scene_fit --seeds 6
	$(BIN)/python -m benchmarks.bench_verify --work out/bench/verify
	$(BIN)/python -m benchmarks.bench_truncation_cost
	$(BIN)/python -m benchmarks.bench_realisations --work out/bench/realisations
	$(BIN)/python -m benchmarks.bench_realisations --work out/bench/realisations --study-seeds 0,1,2,3,4,5,6,7,8,9

clean:
	rm -rf build $(VENV)
