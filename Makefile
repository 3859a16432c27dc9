# Top-level build. `make` builds everything buildable on this host and the
# Python tools; `make test` runs every test; `make run` the demo job on the
# simulated drive; `make bench` prints `name: value unit` lines; `make lint`.
# Everything it needs is installed from scratch (apt, a private apt list for
# Unity, PyPI into .venv) and cached under .cache/.
SHELL := /bin/bash
.DEFAULT_GOAL := all

CACHE      ?= .cache
BUILD      := build
VENV       := .venv
PY         := $(VENV)/bin/python
STAMP      := $(CACHE)/stamps

CC         ?= cc
ARM_CC     := arm-none-eabi-gcc

CORE_SRC   := $(shell find firmware/core -name '*.c' 2>/dev/null | sort)
CORE_HDR   := $(shell find firmware/core firmware/hal -name '*.h' 2>/dev/null | sort)
HIL_SRC    := $(sort $(wildcard hil_sim/*.c) $(wildcard firmware/ports/sim/*.c))
HIL_HDR    := $(sort $(wildcard hil_sim/*.h) $(wildcard firmware/ports/sim/*.h) \
                     $(wildcard firmware/ports/common/*.h))
UNIT_SRC   := $(sort $(wildcard tests/unit/test_*.c))
UNIT_SUP   := $(sort $(wildcard tests/unit/support/*.c))
UNIT_SUP_HDR := $(sort $(wildcard tests/unit/support/*.h))
UNIT_BIN   := $(patsubst tests/unit/%.c,$(BUILD)/unit/%,$(UNIT_SRC))

UNITY_DIR  := $(CACHE)/unity/usr/share/cmock/vendor/unity/src
UNITY_C    := $(UNITY_DIR)/unity.c

INC        := -Ifirmware/core -Ifirmware/hal -Ifirmware -Ihil_sim -Ifirmware/ports/sim
WARN       := -std=c99 -Wall -Wextra -Werror -pedantic
SAN        := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
UNIT_CFLAGS := $(WARN) $(SAN) -g -O1 $(INC) -I$(UNITY_DIR) -Itests/unit/support \
               -D_DEFAULT_SOURCE -DUNITY_INCLUDE_DOUBLE -DUNITY_SUPPORT_64 -DCORE_PREEMPT_TEST
# -O3 -flto: 14 % fewer instructions per simulated tick (bench-hil.sh), the
# same results bit for bit (bench_hil hash; no -ffast-math, contraction off);
# no interposition: calls inside the library need not go through the PLT.
# Across files the link-time pass flags the dispatcher's message locals that
# the generated decoders fill (proto_dispatch.c, proto_msgs.c) as maybe
# uninitialised; the per-file builds (M4 -O2, unit tests) keep that warning.
HOST_OPT   := -O3 -flto=auto -fno-semantic-interposition -Wno-maybe-uninitialized
HOST_CFLAGS := $(WARN) -D_DEFAULT_SOURCE $(HOST_OPT) -g -fPIC -ffp-contract=off $(INC)
M4_CFLAGS  := $(WARN) -mcpu=cortex-m4 -mthumb -mfloat-abi=soft -O2 -ffreestanding \
              -ffunction-sections -fdata-sections $(INC)

.SECONDARY:
.PHONY: all deps venv host test unit m4-check pytest run bench lint fuzz fuzz-short firmware clean distclean proto \
        test-socketcan test-tsan

all: deps venv host

# ---- set-up ---------------------------------------------------------------
deps: $(STAMP)/apt $(UNITY_C)

$(STAMP)/apt: mk/apt-deps.sh
	@mkdir -p $(STAMP)
	./mk/apt-deps.sh
	@touch $@

$(UNITY_C): mk/debian-fetch.sh | $(STAMP)/apt
	./mk/debian-fetch.sh trixie $(CACHE)/unity cmock
	@test -f $@ && touch $@

venv: $(STAMP)/venv

$(STAMP)/venv: host_tools/pyproject.toml | $(STAMP)/apt
	@mkdir -p $(STAMP)
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install -q -e 'host_tools[dev]'
	@touch $@

# ---- protocol: generated from protocol/contour.toml (see protocol/README.md) ----
PROTO_GEN := firmware/core/proto_msgs.h firmware/core/proto_msgs.c \
             host_tools/contour/protocol_gen.py protocol/contour.dbc

CANOPEN_GEN := firmware/core/canopen_od.h firmware/core/canopen_od.c \
               host_tools/contour/canopen_od.py protocol/contour.eds

proto: $(PROTO_GEN) $(CANOPEN_GEN)

$(CANOPEN_GEN) &: protocol/canopen.toml protocol/gen_canopen.py
	python3 protocol/gen_canopen.py
	@touch $(CANOPEN_GEN)

$(PROTO_GEN) &: protocol/contour.toml protocol/gen.py
	python3 protocol/gen.py
	@touch $(PROTO_GEN)

# ---- host build: the core and the simulator as one shared library ---------
host: $(BUILD)/host/libcontour.so

$(BUILD)/host/libcontour.so: $(CORE_SRC) $(HIL_SRC) $(CORE_HDR) $(HIL_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -shared -o $@ $(CORE_SRC) $(HIL_SRC) -lm

# ---- unit tests (Unity, ASan + UBSan) --------------------------------------
# Shared sources are compiled once (sanitized) and linked into every test.
UNIT_LIB_SRC := $(CORE_SRC) $(HIL_SRC) $(UNIT_SUP) $(UNITY_C)
UNIT_LIB_OBJ := $(patsubst %.c,$(BUILD)/unit/obj/%.o,$(UNIT_LIB_SRC))

$(BUILD)/unit/obj/%.o: %.c $(CORE_HDR) $(HIL_HDR) | $(UNITY_C)
	@mkdir -p $(@D)
	$(CC) $(UNIT_CFLAGS) -c -o $@ $<

$(BUILD)/unit/%: tests/unit/%.c $(UNIT_LIB_OBJ) $(CORE_HDR) $(HIL_HDR) $(UNIT_SUP_HDR)
	@mkdir -p $(@D)
	$(CC) $(UNIT_CFLAGS) -o $@ $< $(UNIT_LIB_OBJ) -lm

unit: deps $(UNIT_BIN)
	./tests/run-unit.sh $(UNIT_BIN)

# One module's tests: make unit-fixmath
unit-%: deps $(BUILD)/unit/test_%
	./tests/run-unit.sh $(BUILD)/unit/test_$*

# The tick from a second thread under ThreadSanitizer (docs/tick-main.md): the
# core with CORE_TSAN (shared fields as C11 atomics), the sim HAL, no Unity.
TSAN_SRC := $(CORE_SRC) firmware/ports/sim/hal_sim.c firmware/ports/sim/hal_flash_sim.c
TSAN_BIN := $(BUILD)/tsan/test_tsan_drive

$(TSAN_BIN): tests/tsan/test_tsan_drive.c $(TSAN_SRC) $(CORE_HDR) $(HIL_HDR)
	@mkdir -p $(@D)
	$(CC) -std=c11 -Wall -Wextra -Werror -pedantic -D_DEFAULT_SOURCE -DCORE_TSAN \
	    -fsanitize=thread -g -O1 $(INC) -o $@ $< $(TSAN_SRC) -lpthread -lm

test-tsan: $(TSAN_BIN)
	TSAN_OPTIONS="halt_on_error=1 exitcode=66" $(TSAN_BIN)

# The core must cross-compile for Cortex-M4 cleanly and without floating point.
m4-check: deps
	./mk/m4-check.sh $(CORE_SRC)

pytest: venv host
	$(PY) -m pytest -q tests/python

test: deps lint unit test-tsan fuzz-short m4-check pytest test-socketcan

# ---- real targets: STM32F4 and QEMU mps2-an386 images (docs/ports.md) --------
firmware: deps venv
	./mk/firmware.sh

# The Linux port's SocketCAN link inside a QEMU guest with vcan (about 30-60 s).
test-socketcan: deps venv
	./tests/ports/socketcan/run.sh

# ---- fuzzing: libFuzzer harnesses (clang) of the frame decoder and dispatcher ----
# `make fuzz` is the long run; `make test` runs the short one (FUZZ_SHORT_RUNS
# executions per harness from the kept corpus, about 20 s in all).
FUZZ_RUNS ?= 1000000
FUZZ_SHORT_RUNS ?= 5000
fuzz: deps
	./tests/fuzz/run.sh $(FUZZ_RUNS)

fuzz-short: deps
	./tests/fuzz/run.sh $(FUZZ_SHORT_RUNS)

# ---- demo, benchmarks, lint ------------------------------------------------
run: all
	./mk/run-demo.sh

bench: all
	./bench/run.sh

lint: all
	./mk/lint.sh

clean:
	rm -rf $(BUILD)

distclean: clean
	rm -rf $(CACHE) $(VENV)
