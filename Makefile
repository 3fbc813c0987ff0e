# vcigen: two commands set everything up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
OUT    ?= results
JOBS   ?= auto
# make test builds the suite's C libraries at -O0: the shipped flags (vcigen/backends/c.py CFLAGS) but the
# optimisation level, a fifth of the compiler's time and the same numbers bit for bit (x86-64, no
# -ffast-math); tests/test_shipped_flags.py builds every template branch at the shipped -O2 -Werror.
TEST_CC_OPT ?= -O0

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
	VCIGEN_CC_OPT=$(TEST_CC_OPT) $(PY) -m pytest -q -n $(JOBS) --dist loadfile

lint: venv
	$(VENV)/bin/ruff check vcigen tests examples bench

generate: venv        ## regenerate generated/ from the examples (one command)
	$(VENV)/bin/vcigen generate --all

# the benches time the shipped build (-O2), whatever the shell exports
bench: export VCIGEN_CC_OPT := -O2
bench: venv           ## speed against error, side by side; forced and frictional scenes with the engines that install
	for e in mujoco pymunk pybullet; do $(VENV)/bin/pip install -q $$e || echo "$$e does not install here: the benches skip it"; done
	$(PY) bench/run.py
	$(PY) bench/forced.py
	$(PY) bench/friction.py

clean:
	rm -rf $(OUT) .pytest_cache build dist *.egg-info
