# The two commands of the README: `make demo` and `make test`. Both set up what they need first.
PY := .venv/bin/python
SETUP_STAMP := .venv/.setup-stamp
SETUP_INPUTS := requirements.txt scripts/setup.sh $(wildcard src/*/setup.py)
# The real-rclpy tier (.venv-ros); its stamp is outside the venv since setup may skip the venv.
ROS_STAMP := build/.setup-ros-stamp
ROS_INPUTS := $(SETUP_INPUTS) requirements-ros.txt scripts/setup_ros.sh scripts/gen_interfaces.py \
	msgs/CMakeLists.txt msgs/package.xml $(wildcard msgs/msg/*.msg) \
	$(wildcard src/vizzy_runtime/vizzy_runtime/interfaces/*/msg/*.msg)

.PHONY: setup setup-ros demo test lint bench clean

# .venv: what the demo, the benches and the bundled-runtime tests need; .venv-ros: the real-rclpy
# tier on top of it (make test, make setup-ros).
setup: $(SETUP_STAMP) $(ROS_STAMP)
setup-ros: $(ROS_STAMP)

$(SETUP_STAMP): $(SETUP_INPUTS)
	bash scripts/setup.sh
	touch $@

$(ROS_STAMP): $(ROS_INPUTS) $(SETUP_STAMP)
	bash scripts/setup_ros.sh
	mkdir -p $(dir $@) && touch $@

demo: $(SETUP_STAMP)
	$(PY) -m vizzy_runtime.demo

# Two tiers: everything on the bundled runtime, then the live-node, whole-graph and mixed-vendor
# tests again on ROS 2 Jazzy's own rclpy (scripts/test_ros.sh says so when that tier is skipped).
test: setup
	$(PY) -m pytest
	bash scripts/test_ros.sh

# ruff (ruff.toml: the project's rule set) over everything, mypy (mypy.ini) over every package.
lint: $(SETUP_STAMP)
	.venv/bin/ruff check .
	.venv/bin/mypy

bench: setup
	@for b in bench/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf .venv .venv-ros .venv-ros.skipped build install log demo_output .pytest_cache
