# The two commands of the README: `make demo` and `make test`. Both set up what they need first.
PY := .venv/bin/python
SETUP_STAMP := .venv/.setup-stamp
SETUP_INPUTS := requirements.txt scripts/setup.sh $(wildcard src/*/setup.py)

.PHONY: setup demo test bench clean

setup: $(SETUP_STAMP)

$(SETUP_STAMP): $(SETUP_INPUTS)
	bash scripts/setup.sh
	touch $@

demo: setup
	$(PY) -m vizzy_runtime.demo

test: setup
	$(PY) -m pytest

bench: setup
	@for b in bench/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf .venv build install log demo_output .pytest_cache
