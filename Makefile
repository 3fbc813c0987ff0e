# vcigen: two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
OUT    ?= results
JOBS   ?= auto

.PHONY: venv demo test test-fast lint generate bench clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: venv            ## the paper's examples on both backends: CSV + energy plots in $(OUT)/
	$(PY) examples/particle.py --out $(OUT) --backend c
	$(PY) examples/star.py --out $(OUT) --backend c
	$(PY) examples/particle.py --out $(OUT)
	$(PY) examples/star.py --out $(OUT)
	$(PY) examples/contact/ball_to_rest.py --out $(OUT) --backend c
	$(PY) examples/forced/impact_oscillator.py --out $(OUT) --backend c

test: venv            ## the whole test suite, on every core (pytest-xdist, a file per worker: its builds once; JOBS=1 for one process)
	$(PY) -m pytest -q -n $(JOBS) --dist loadfile

lint: venv
	$(VENV)/bin/ruff check vcigen tests examples bench

generate: venv        ## regenerate generated/ from the examples (one command)
	$(VENV)/bin/vcigen generate --all

bench: venv           ## speed against error, side by side; forced and frictional scenes with the engines that install
	for e in mujoco pymunk pybullet; do $(VENV)/bin/pip install -q $$e || echo "$$e does not install here: the benches skip it"; done
	$(PY) bench/run.py
	$(PY) bench/forced.py
	$(PY) bench/friction.py

clean:
	rm -rf $(OUT) .pytest_cache build dist *.egg-info
