# The two entry points of the README. Each installs what it needs from uv.lock first.
UV := python3 -m uv
PYTEST_ARGS ?= -m "not slow"

.PHONY: demo test test-all setup install docs

# Bytecode compiled at install: every Ray worker process imports Ray and the simulators, at
# half the CPU with .pyc files (which PYTHONDONTWRITEBYTECODE=1 would never let Python write).
# Then the compile caches (Pooltool, Kinetix: minutes, once per machine and uv.lock), so no
# first run waits for them; .venv/.warm-up records that it was done. The demo (I-PHYRE, which
# compiles nothing) needs only the install, so its first run does not wait for the warm-up.
install:
	@$(UV) --version >/dev/null 2>&1 || python3 -m pip install -q uv
	@$(UV) sync --frozen -q --compile-bytecode

setup: install
	@$(MAKE) -s .venv/.warm-up

.venv/.warm-up: uv.lock
	$(UV) run --frozen python -m deepphy.warm_up
	@touch $@

# The main job: all 40 I-PHYRE games x 3 runs with MOCK on a local 2-CPU Ray, then the report.
demo: install
	$(UV) run --frozen deepphy run --env iphyre --model mock --format vla --runs 3 --out runs/demo
	$(UV) run --frozen deepphy report runs/demo

test: setup
	$(UV) run --frozen pytest $(PYTEST_ARGS)

test-all: setup
	$(UV) run --frozen pytest -m ""

# The documentation site (docs/, mkdocs.yml) into site/; a test builds it with --strict too.
docs: install
	NO_MKDOCS_2_WARNING=1 $(UV) run --frozen mkdocs build --strict --quiet
