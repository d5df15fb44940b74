# vesica — build, test, bench, run.  `make test` and `make run` install any
# missing Debian package first (as root), then build and run.
#
#   make            build build/libvesica.a and build/vesica
#   make test       every test in tests/ (SAN=1: AddressSanitizer + UBSan)
#   make valgrind   the small cases under valgrind (tests/valgrind.sh)
#   make test-slurm a study through a real single-node Slurm (installs, starts daemons)
#   make bench      the benchmarks in bench/, printing tables
#   make run        the default problem (results/oblate.h5, .xdmf, PNG figures)
#   make deps       install missing Debian packages (root) or print the command
#   make format     clang-format every C/C++ file (format-check: only report)
#   make check-layers   the include graph against the layers (tests/check_layers.py)
#   make check-history  no words about the making of the code in tracked files
#   make clean

CC      ?= gcc
CXX     ?= g++
SAN     ?= 0
OPT     ?= -O2
ifeq ($(SAN),1)
BUILD   ?= build-san
SANFLAGS = -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined
# libhdf5's own leaks on a failed open of a damaged file are not ours (the
# tests that cut files short meet them as the fuzzer does: tests/fuzz/lsan.supp)
LSAN_OPTIONS ?= suppressions=$(CURDIR)/tests/fuzz/lsan.supp
export LSAN_OPTIONS
else
BUILD   ?= build
SANFLAGS =
endif

# python3-meshio and python3-h5py: test_cli reads the output with them
# (tests/xdmf_check.py), readers that share no code with vesica;
# clang-format: make format-check (the first step of .ci/run); libsuitesparse-dev:
# CHOLMOD, the nlopt backend's exact sparse Cholesky factor (solver/linalg/chol.c)
DEPS_PKGS = coinor-libipopt-dev libnlopt-dev libmumps-seq-dev libcgal-dev \
            libhdf5-dev libcmocka-dev liblapacke-dev libopenblas-dev \
            gnuplot-nox pkg-config libsuitesparse-dev python3-meshio python3-h5py clang-format

PKG_CFLAGS := $(shell pkg-config --cflags ipopt hdf5 2>/dev/null)
PKG_LIBS   := $(shell pkg-config --libs ipopt hdf5 2>/dev/null)

WARN     = -Wall -Wextra -Wshadow -Wmissing-prototypes -Wstrict-prototypes -Wvla -Werror
CFLAGS  ?= $(OPT) -g
CFLAGS  += -std=c11 -fopenmp -D_XOPEN_SOURCE=700 $(WARN) -Iinclude -Isolver $(PKG_CFLAGS) $(SANFLAGS) -MMD -MP
# CGAL: always -O2 (16x slower at -O0); rounding-math as CGAL requires, and the
# check disabled so valgrind can run it.
CXXFLAGS_CGAL = -std=c++17 -O2 -g -fopenmp -frounding-math -DCGAL_DISABLE_ROUNDING_MATH_CHECK \
                -Wall -Wextra -Werror -Iinclude $(SANFLAGS) -MMD -MP
LDLIBS   = $(PKG_LIBS) -lnlopt -ldmumps_seq -lsmumps_seq -lcholmod -llapacke -lopenblas -lgmp -lstdc++ -lm
LDFLAGS += $(SANFLAGS) -fopenmp

# The library's layers, lowest first (docs/design.md, "Layers and interfaces"); the program
# (command line, problem files, output, plots, studies) in solver/app.
LAYERS   = core linalg discret model step backends time analysis
LIB_C    = $(foreach l,$(LAYERS),$(wildcard solver/$(l)/*.c))
LIB_CXX  = $(foreach l,$(LAYERS),$(wildcard solver/$(l)/*.cpp))
APP_C    = $(wildcard solver/app/*.c)
CLI_OBJ  = $(APP_C:solver/%.c=$(BUILD)/obj/%.o)
LIB_OBJ  = $(LIB_C:solver/%.c=$(BUILD)/obj/%.o) $(LIB_CXX:solver/%.cpp=$(BUILD)/obj/%.o)
# the longest first (by their times under SAN=1): tests/run.sh
# runs them two at a time, each lane taking the next one not yet taken
TESTS_LONG = test_integrate test_cli_restart test_cli test_cli_disk test_backend test_spectrum test_model test_model_flow test_remesh test_cli_files test_cli_guard
TESTS    = $(addprefix $(BUILD)/tests/,$(TESTS_LONG)) \
           $(filter-out $(addprefix $(BUILD)/tests/,$(TESTS_LONG)), \
             $(patsubst tests/%.c,$(BUILD)/tests/%,$(wildcard tests/test_*.c))) \
           tests/test_reader.py tests/test_series_tsv.py
BENCHES  = $(patsubst bench/%.c,$(BUILD)/bench/%,$(wildcard bench/bench_*.c))
# make bench runs them all with their defaults (hours: bench_table1 and
# bench_robust include explicit Euler and NLopt); docs/results.md gives the
# command of every table, e.g. make bench BENCH_ONLY=bench_mode.
BENCH_ONLY ?= 

.PHONY: all deps test test-build test-slow test-slurm valgrind bench run paper clean format format-check \
        check-layers check-history
# (a sub-make, as test and run do: the pkg-config flags above are read when
# this Makefile is parsed, i.e. before deps installs ipopt and hdf5 on a
# fresh machine)
all: deps
	@$(MAKE) --no-print-directory $(BUILD)/libvesica.a $(BUILD)/vesica

$(BUILD)/obj/%.o: solver/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) -c $< -o $@
# The provenance every output file records (solver/app/io_provenance.c): the
# commit built (git describe --always --dirty; "unknown" outside a git
# checkout) and the compiler flags. Only that object is rebuilt when they
# change: it depends on a stamp rewritten only then.
VES_COMMIT := $(shell git describe --always --dirty 2>/dev/null || echo unknown)
PROV_CFLAGS := $(strip $(CFLAGS))
$(BUILD)/provenance.stamp: FORCE
	@mkdir -p $(@D); printf '%s\n' "$(VES_COMMIT) $(PROV_CFLAGS)" | cmp -s - $@ || \
	  printf '%s\n' "$(VES_COMMIT) $(PROV_CFLAGS)" > $@
$(BUILD)/obj/app/io_provenance.o: $(BUILD)/provenance.stamp
$(BUILD)/obj/app/io_provenance.o: CFLAGS += -DVES_COMMIT='"$(VES_COMMIT)"' -DVES_CFLAGS='"$(PROV_CFLAGS)"'
.PHONY: FORCE
FORCE:
$(BUILD)/obj/%.o: solver/%.cpp
	@mkdir -p $(@D)
	$(CXX) $(CXXFLAGS_CGAL) -c $< -o $@
# (made anew each time: an object whose source is gone must not linger)
$(BUILD)/libvesica.a: $(LIB_OBJ)
	rm -f $@ && ar rcs $@ $^
# the program's objects (solver/app) in an archive of their own, which the
# tests of the program link too
$(BUILD)/libvesica_app.a: $(CLI_OBJ)
	rm -f $@ && ar rcs $@ $^
$(BUILD)/vesica: $(CLI_OBJ) $(BUILD)/libvesica.a
	$(CC) $(LDFLAGS) -o $@ $(CLI_OBJ) $(BUILD)/libvesica.a $(LDLIBS)
$(BUILD)/tests/%: tests/%.c $(BUILD)/libvesica_app.a $(BUILD)/libvesica.a | $(BUILD)/tests
	$(CC) $(CFLAGS) -o $@ $< $(BUILD)/libvesica_app.a $(BUILD)/libvesica.a $(LDFLAGS) -lcmocka $(LDLIBS)
$(BUILD)/bench/%: bench/%.c $(BUILD)/libvesica_app.a $(BUILD)/libvesica.a | $(BUILD)/bench
	$(CC) $(CFLAGS) -o $@ $< $(BUILD)/libvesica_app.a $(BUILD)/libvesica.a $(LDFLAGS) $(LDLIBS)
# the independent Stokes prediction of the shape-mode decay: self-contained
# (no libvesica: it checks the solver's time scale from outside)
$(BUILD)/bench/stokes_mode: bench/stokes_mode.c | $(BUILD)/bench
	$(CC) -std=c11 $(OPT) -Wall -Wextra -Werror -o $@ $< -ldmumps_seq -llapacke -lopenblas -lm
$(BUILD)/tests $(BUILD)/bench:
	mkdir -p $@

# Install what is missing (root), or say what to run. Costs one dpkg-query
# when everything is there.
deps:
	@st=$$(dpkg-query -W -f='$${Package} $${Status}\n' $(DEPS_PKGS) 2>/dev/null); missing=; \
	for p in $(DEPS_PKGS); do \
	  printf '%s\n' "$$st" | grep -q "^$$p install ok installed$$" || missing="$$missing $$p"; \
	done; \
	[ -z "$$missing" ] && exit 0; \
	echo "vesica: missing Debian packages:$$missing"; \
	if [ "$$(id -u)" = 0 ]; then \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	else \
	  echo "run as root: apt-get update && apt-get install -y --no-install-recommends$$missing"; exit 1; \
	fi

test: test-build
	@VESICA=$(CURDIR)/$(BUILD)/vesica OPENBLAS_NUM_THREADS=1 sh tests/run.sh $(TESTS)

# what make test runs, built (.ci/run builds it beside make valgrind)
test-build: deps
	@$(MAKE) --no-print-directory $(BUILD)/libvesica.a $(BUILD)/vesica $(TESTS) $(BENCHES)

# the small cases under valgrind (memcheck, no SAN build): ~4 min
valgrind: deps
	@$(MAKE) --no-print-directory SAN=0 BUILD=build build/vesica
	@sh tests/valgrind.sh build/vesica

# the slow cases too (the full NLopt-vs-Ipopt step comparison, ~3 min)
test-slow:
	@VESICA_SLOW_TESTS=1 $(MAKE) --no-print-directory test

# `vesica study` through a real Slurm on this machine (tests/slurm_roundtrip.sh,
# root): installs slurm-wlm and munge if missing, starts a private munged,
# slurmctld and slurmd, submits a 4-cell study, collects, compares with the
# local run, stops the daemons. 20-30 s once installed. Not part of make test.
test-slurm: deps
	@$(MAKE) --no-print-directory $(BUILD)/vesica
	@sh tests/slurm_roundtrip.sh $(BUILD)/vesica

# Fuzzing (not part of make test): libFuzzer through clang (installed here if
# missing, as root), with AddressSanitizer + UBSan, on the problem-file parser
# and --set overrides (tests/fuzz/fuzz_config.c), the points-file reader
# with the curve shape built from it (tests/fuzz/fuzz_points.c) and the
# HDF5 output reader of info, plot and run --restart, salvage included
# (tests/fuzz/fuzz_h5.c; our code instrumented, libhdf5 not), the study-file
# parser with the Slurm script's quoting (tests/fuzz/fuzz_study.c), for
# FUZZ_SECONDS each (default 120) from the seed FUZZ_SEED (FUZZ_ONLY=h5 etc.
# runs one). Corpus: the seeds tests/fuzz/seeds/, problems/*.ini,
# data/cup.txt and problems/studies/*.ini; for the HDF5 reader, files of
# two small runs of the freshly built vesica (tests/fuzz/h5_seeds.sh: ~190
# and ~500 KB, too large to commit) and copies cut short; grown in $(BUILD)/fuzz/corpus_*; a crash or a
# broken contract stops it (exit 1) and leaves the input as
# $(BUILD)/fuzz/crash-*.
FUZZ_SECONDS ?= 120
FUZZ_SEED    ?= 1
FUZZ_ONLY    ?=
FUZZ_CFLAGS   = -std=c11 -D_XOPEN_SOURCE=700 -O1 -g -fno-omit-frame-pointer -Iinclude -Isolver \
                -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
# ASan's malloc returns NULL for a request it cannot serve, as glibc's does
# (a damaged HDF5 header asks libhdf5 for petabytes; it copes), and only
# memory really used counts (-rss_limit_mb 2048), not the size asked for;
# libhdf5's own over-reads and leaks are not ours (tests/fuzz/*.supp): a
# crash in it still stops the fuzzer
FUZZ_RUN      = cd $(BUILD)/fuzz && UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
                ASAN_OPTIONS=allocator_may_return_null=1:suppressions=$(CURDIR)/tests/fuzz/asan.supp \
                LSAN_OPTIONS=suppressions=$(CURDIR)/tests/fuzz/lsan.supp \
                ./fuzz_$(1) -seed=$(FUZZ_SEED) -max_total_time=$(FUZZ_SECONDS) -max_len=$(2) \
                -malloc_limit_mb=1048576 -print_final_stats=1 corpus_$(1)
.PHONY: fuzz
fuzz: deps
	@[ "$$(dpkg-query -W -f='$${Status}\n' clang libclang-rt-14-dev 2>/dev/null | grep -c '^install ok installed$$')" = 2 ] || \
	{ if [ "$$(id -u)" = 0 ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
	  apt-get install -y -qq --no-install-recommends clang libclang-rt-14-dev; \
	  else echo "run as root: apt-get install -y --no-install-recommends clang libclang-rt-14-dev"; exit 1; fi; }
	@mkdir -p $(BUILD)/fuzz/corpus_config $(BUILD)/fuzz/corpus_points $(BUILD)/fuzz/corpus_h5 \
	  $(BUILD)/fuzz/corpus_study
	clang $(FUZZ_CFLAGS) -o $(BUILD)/fuzz/fuzz_config tests/fuzz/fuzz_config.c solver/core/status.c -lm
	clang $(FUZZ_CFLAGS) -o $(BUILD)/fuzz/fuzz_points tests/fuzz/fuzz_points.c solver/app/config.c \
	  solver/discret/shape.c solver/core/status.c -lm
	clang $(FUZZ_CFLAGS) $$(pkg-config --cflags hdf5) -o $(BUILD)/fuzz/fuzz_h5 tests/fuzz/fuzz_h5.c \
	  $(wildcard solver/app/io*.c) solver/app/plot.c solver/analysis/level_set.c solver/app/config.c solver/core/status.c \
	  $$(pkg-config --libs hdf5) -lm
	clang $(FUZZ_CFLAGS) $$(pkg-config --cflags hdf5) -o $(BUILD)/fuzz/fuzz_study tests/fuzz/fuzz_study.c \
	  solver/app/study.c $(wildcard solver/app/io*.c) solver/app/plot.c solver/analysis/level_set.c \
	  solver/app/config.c solver/core/status.c $$(pkg-config --libs hdf5) -lm
	@cp problems/*.ini tests/fuzz/seeds/*.ini tests/fuzz/seeds/set_*.txt $(BUILD)/fuzz/corpus_config/
	@cp data/cup.txt tests/fuzz/seeds/*.txt $(BUILD)/fuzz/corpus_points/
	@cp problems/studies/*.ini $(BUILD)/fuzz/corpus_study/
	@case h5 in *"$(FUZZ_ONLY)"*) $(MAKE) --no-print-directory $(BUILD)/vesica && \
	  sh tests/fuzz/h5_seeds.sh $(BUILD)/vesica $(BUILD)/fuzz/corpus_h5;; esac
	@case config in *"$(FUZZ_ONLY)"*) $(call FUZZ_RUN,config,8192);; esac
	@case points in *"$(FUZZ_ONLY)"*) $(call FUZZ_RUN,points,8192);; esac
	@case h5 in *"$(FUZZ_ONLY)"*) $(call FUZZ_RUN,h5,600000);; esac
	@case study in *"$(FUZZ_ONLY)"*) $(call FUZZ_RUN,study,8192);; esac

bench: deps
	@$(MAKE) --no-print-directory $(BUILD)/libvesica.a $(BUILD)/vesica $(BENCHES)
	@$(MAKE) --no-print-directory $(BUILD)/bench/stokes_mode
	@for b in $(BENCHES) $(BUILD)/bench/stokes_mode; do \
	  case "$$b" in *"$(BENCH_ONLY)"*) ;; *) continue;; esac; \
	  echo "== $$b"; OPENBLAS_NUM_THREADS=1 $$b || exit 1; done
	@case sphere_convergence in *"$(BENCH_ONLY)"*) \
	  echo "== bench/sphere_convergence.sh"; sh bench/sphere_convergence.sh $(BUILD)/vesica;; esac
	@case reconnect_table in *"$(BENCH_ONLY)"*) \
	  echo "== bench/reconnect_table.sh"; OPENBLAS_NUM_THREADS=1 VESICA=$(BUILD)/vesica \
	  sh bench/reconnect_table.sh;; esac
	@case scale in *"$(BENCH_ONLY)"*) \
	  echo "== bench/scale.sh"; BENCH_SCALE=$(BUILD)/bench/bench_scale sh bench/scale.sh \
	    > $(BUILD)/scale.tsv; rc=$$?; cat $(BUILD)/scale.tsv; \
	  sh bench/scale_plot.sh $(BUILD)/scale.tsv $(BUILD)/scale_step.png && exit $$rc;; esac

# The default run: the oblate relaxation of problems/oblate.ini (paper
# Figs. 3-4, under a minute on 2 cores) to results/oblate.h5 (+ .xdmf) and its
# figures results/oblate_*.png (replacing those of an earlier make run:
# --force).
run: deps
	@$(MAKE) --no-print-directory $(BUILD)/vesica
	@mkdir -p results
	OPENBLAS_NUM_THREADS=1 $(BUILD)/vesica run problems/oblate.ini --out results/oblate.h5 --force
	$(BUILD)/vesica plot results/oblate.h5 --outdir results --force

# The paper's results (bench/paper.sh): every finished run kept in
# results/paper/ and skipped next time, an interrupted one continued;
# figures in bench/figures/paper/, the table in bench/PAPER.md. PAPER_EPS
# sets eps/R0 of every run (0.01: the paper's scale) and gives the scale
# files of its own (results/paper_eps0.01/, bench/figures/paper_eps0.01/,
# bench/PAPER_eps0.01.md), PAPER_ONLY a subset, PAPER_JOBS the runs at a
# time (default 2, one thread each).
PAPER_EPS ?=
PAPER_ONLY ?=
PAPER_JOBS ?= 2
paper: deps
	@$(MAKE) --no-print-directory $(BUILD)/vesica $(BUILD)/bench/bench_table1
	@VESICA=$(BUILD)/vesica TABLE1=$(BUILD)/bench/bench_table1 PAPER_EPS=$(PAPER_EPS) \
	  PAPER_ONLY=$(PAPER_ONLY) PAPER_JOBS=$(PAPER_JOBS) sh bench/paper.sh

# Every C/C++ file of the repository, formatted by .clang-format: format
# rewrites them, format-check only reports (exit 1 and the lines that differ;
# .ci/run runs it). The cmocka test tables stay packed (clang-format off).
FORMAT_FILES = $(wildcard include/ves/*.h solver/*/*.c solver/*/*.h solver/*/*.cpp tests/*.c \
                 tests/*.h tests/fuzz/*.c bench/*.c bench/*.h)
format:
	clang-format -i --style=file $(FORMAT_FILES)
format-check: deps
	@command -v clang-format >/dev/null || { echo "format-check: clang-format not found (apt-get install clang-format)"; exit 1; }
	@clang-format --dry-run -Werror --style=file $(FORMAT_FILES) 2>&1 | \
	  awk '/error:/ {n++; split($$0, p, ":"); f[p[1]]++} {print} \
	       END {if (n) {printf "format-check: %d place(s) in %d file(s) differ from .clang-format " \
	            "(make format fixes them)\n", n, length(f); exit 1} else print "format-check: ok"}'

# The layer rules of docs/design.md, "Layers and interfaces": no library
# folder includes a program header (solver/app) or a private header of another
# folder, every arrow of the include graph points down (make check-layers;
# tests/check_layers.py --dot draws the graph).
check-layers:
	@python3 tests/check_layers.py

# The repository speaks of the software only: tracked files name no work
# periods or tracker numbers (the pattern is split so this line does not
# match itself).
HISTORY_RE = \bsess''ion|iss''ue [0-9]
check-history:
	@printf 'in sess''ion 3\nsee iss''ue 21\n' | [ "$$(grep -ciE '$(HISTORY_RE)')" = 2 ] || \
	  { echo "check-history: the pattern misses its own examples"; exit 1; }
	@if git grep -nIiE '$(HISTORY_RE)' -- . ; then \
	  echo "check-history: the lines above speak of the making of the code, not of the code"; exit 1; \
	else echo "check-history: ok"; fi

clean:
	rm -rf build build-san

-include $(wildcard $(BUILD)/obj/*/*.d $(BUILD)/tests/*.d $(BUILD)/bench/*.d)
