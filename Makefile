# One command per job; each installs what is missing first.
#   make demo    install, then run the main job on the built-in defaults
#   make check   lint (ruff) and types (mypy), configured in pyproject.toml
#   make test    the whole test suite (about a minute; `make test-fast` skips the slow marker)
#   make bench   benchmarks against open-source peers (separate env .venv-bench)

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SOURCES := pyproject.toml CMakeLists.txt $(wildcard rcwa/cpp/*.cpp rcwa/cpp/*.hpp)

.PHONY: install demo check test test-fast bench clean

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

check: install
	$(BIN)/ruff check .
	$(BIN)/mypy

test: install
	$(BIN)/python -m pytest -q

test-fast: install
	$(BIN)/python -m pytest -q -m "not slow"

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
	$(BIN)/python -m benchmarks.bench_calibration

clean:
	rm -rf build $(VENV)
