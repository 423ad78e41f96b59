# The two commands of the README: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: test demo lint venv clean bench bench-quick browser mutation planted

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

lint: $(STAMP)
	$(BIN)/ruff check controller drivers calibration tests bench mutation
	$(BIN)/mypy

test: lint browser
	$(BIN)/pytest -q

# The operator station's browser tests need Chromium and its driver (Debian packages). Installed
# here when missing and we may (root with apt-get); otherwise those tests skip, saying why.
browser:
	@if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  echo "installing chromium and chromium-driver (Debian) for the browser tests"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    chromium chromium-driver >/dev/null) || echo "could not install Chromium: the browser tests will skip"; \
	else echo "no Chromium and not root: the browser tests will skip (apt-get install chromium chromium-driver)"; fi

demo: $(STAMP)
	$(BIN)/seamguide dry-run --output out/dry-run

bench: $(STAMP)
	$(BIN)/python bench/run_all.py

bench-quick: $(STAMP)
	$(BIN)/python bench/run_all.py --quick

# Safety paths (issue 19; README "Safety"): not in make test or CI, they take long.
# planted: the 21 hand-planted bugs, each must fail a test. mutation: cosmic-ray over the
# functions that carry the safety checks; survivors go to mutation/survivors.md.
planted: $(STAMP)
	$(BIN)/python mutation/planted.py

mutation: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,mutation]'
	$(BIN)/python mutation/run.py

clean:
	rm -rf $(VENV) build *.egg-info
