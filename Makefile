# The two entry points of the README. Each installs what it needs from uv.lock first.
UV := python3 -m uv
PYTEST_ARGS ?= -m "not slow"

.PHONY: demo test test-all setup

setup:
	@$(UV) --version >/dev/null 2>&1 || python3 -m pip install -q uv
	@$(UV) sync --frozen -q

# The main job: all 40 I-PHYRE games x 3 runs with MOCK on a local 2-CPU Ray, then the report.
demo: setup
	$(UV) run --frozen deepphy run --env iphyre --model mock --format vla --runs 3 --out runs/demo
	$(UV) run --frozen deepphy report runs/demo

test: setup
	$(UV) run --frozen pytest $(PYTEST_ARGS)

test-all: setup
	$(UV) run --frozen pytest -m ""
