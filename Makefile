# Two entry points a new user needs: `make demo` and `make test` (see README.md).
# Both set everything up first; setup is idempotent and only redoes what changed.
SHELL := /bin/bash
PY ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
WS := ros2_ws
PKGS := rftgls_conventions rftgls_node_base rftgls_core minirquad_driver minirquad_sim rftgls_ros
PKG_FILES := $(foreach p,$(PKGS),src/$(p)/setup.py src/$(p)/setup.cfg src/$(p)/package.xml)
# Packages built by colcon only (interfaces: ament_cmake + rosidl; the robot description: data);
# any change re-builds them.
WS_PKGS := tf2_msgs rftgls_interfaces minirquad_description
WS_FILES := $(shell find $(foreach p,$(WS_PKGS),src/$(p)) -type f 2>/dev/null)
# Every package of the workspace, for `make colcon-test` (colcon here has no `list` verb).
COLCON_PKGS := $(PKGS) $(WS_PKGS)
# DDS stays on loopback for everything started from here (discovery and sockets).
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export FASTRTPS_DEFAULT_PROFILES_FILE := $(CURDIR)/ros2_ws/params/fastdds_localhost.xml
export FASTDDS_DEFAULT_PROFILES_FILE := $(FASTRTPS_DEFAULT_PROFILES_FILE)
export MPLBACKEND := Agg
ENV := source tools/env.sh
# worksteal: an idle worker takes queued tests from the busy one, so the long end-to-end tests
# do not leave one worker running alone at the end (first phase 5:34 -> 4:41 on this machine).
PYTEST_ARGS ?= -n 2 --dist worksteal
# make test's first phase (no real-time test in it) has a third worker on the two cores: its
# stacks and subprocesses wait, and two workers kept 1.7 of the 2 cores busy (5:37 -> 4:35).
FIRST_PHASE_ARGS ?= -n 3 --dist worksteal
# The folders that hold the real-time tests: the last two phases collect only these (3.6 s of
# the 6.4 s a phase spends collecting); tests/test_realtime_folders.py fails on a real-time
# test anywhere else.
REALTIME_TESTS := tests/driver tests/stack

.PHONY: setup build demo teleop-sim test test-campaign test-cpus colcon-test lint bench lock clean firmware firmware-size

# Two jobs for the steps that can share the 2-core machine, unless `make -jN` already shares
# its jobs with this make (a sub-make's own -j would leave the caller's job count).
JOBS2 = $(if $(findstring jobserver,$(MAKEFLAGS)),,-j2)

# The firmware (g++ only) compiles while pip installs; the workspace builds after pip.
setup:
	$(MAKE) $(JOBS2) $(STAMP) firmware
	$(MAKE) $(BIN)/ros2 $(WS)/install/.built-stamp

# The MiniRQuad firmware's host build (g++ with AddressSanitizer + UBSan): its unit tests, the
# fuzz test and fw_sitl, the compiled firmware `minirquad_sim --mcu firmware` runs on the pty.
# Two compile jobs: 7 s instead of 14 s of a fresh setup on the 2-core machine (under `make
# setup` it shares the two jobs with pip).
FIRMWARE := src/minirquad_driver/firmware
firmware:
	$(MAKE) -s $(JOBS2) -C $(FIRMWARE) host

# The firmware core cross-compiled for the robot's Cortex-M0+ (gcc-arm-none-eabi): flash and
# RAM against the MKR WiFi 1010's 256 KB / 32 KB; fails if over or if heap use is linked in.
firmware-size:
	$(MAKE) -s -C $(FIRMWARE) size

# The ros2 stand-in is re-installed when it changes (it applies the DDS loopback profile).
$(BIN)/ros2: tools/ros2 $(STAMP)
	install -m 755 tools/ros2 $@

# pip byte-compiles what it installs (a third of the install, 17 s fresh): skipping it left
# the compile to each process's first import, and where PYTHONDONTWRITEBYTECODE is set to
# every import (a node's imports: 1.7-2.3 s with bytecode, 4.6-5.6 s without).
$(STAMP): requirements/lock.txt $(PKG_FILES)
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --disable-pip-version-check -q --no-deps --require-hashes \
	    -r requirements/lock.txt
	$(BIN)/python -m pip check
	$(BIN)/python -m pip install --disable-pip-version-check -q --no-deps --no-build-isolation \
	    $(foreach p,$(PKGS),-e src/$(p))
	$(BIN)/python tools/fix_rosidl_cmake.py
	install -m 755 tools/ros2 tools/rftgls $(BIN)/
	touch $@

# colcon gives the ament layout (lib/<pkg>/<exe>) that `ros2 run` looks up. The interface
# packages find the rosidl generators and type supports through AMENT_PREFIX_PATH = the venv
# (docs/design/ros2-from-pip.md, "Interface packages from pip").
# The parallel executor builds the two interface packages side by side (49 s -> 39 s).
$(WS)/install/.built-stamp: $(STAMP) $(PKG_FILES) $(WS_FILES)
	source $(BIN)/activate && cd $(WS) && AMENT_PREFIX_PATH=$(CURDIR)/$(VENV) colcon build \
	    --executor parallel --symlink-install --cmake-args -DBUILD_TESTING=ON -DPython3_EXECUTABLE=$(CURDIR)/$(BIN)/python
	touch $@

build: setup

# The teleoperated tug on the simulated MiniRQuad: simulator, serial bridge, capacity_node and
# state_publisher (launch/teleop.launch.py, run by the project's launch stand-in); then
# `source tools/env.sh && ros2 run rftgls_ros teleop` in a second terminal (same ROS_DOMAIN_ID).
SLED ?= 0.4
teleop-sim: setup
	$(ENV) && python -m rftgls_ros.launch_run src/rftgls_ros/launch/teleop.launch.py \
	    sled_mass_kg:=$(SLED) port:=/tmp/minirquad_sim_tty_$$ROS_DOMAIN_ID

# The simulated MiniRQuad, the serial bridge, capacity_node and behavior_node: three
# walk-burrow-tug cycles with a 400 g sled and three with a 600 g sled (picks its own
# ROS_DOMAIN_ID; DDS on loopback). `rftgls demo` is the ROS-free capacity table.
demo: setup
	$(ENV) && unset ROS_DOMAIN_ID && ros2 run rftgls_ros behavior_demo --out out/demo

# Three phases: everything else on three workers; then the real-time end-to-end tests, two at
# a time (a CPU-heavy test on the other worker can stall a whole simulated stack for seconds on
# 2 cores, another stack does not; a test is `realtime` only if it fails under load); last the
# stop campaign by itself, which loads both cores on purpose (docs/design/deviations.md). Each
# claim once; its repetitions and variants are the campaign below.
test: setup
	$(ENV) && python -m pytest tests $(FIRST_PHASE_ARGS) -m "not realtime and not campaign" \
	    && python -m pytest $(REALTIME_TESTS) $(PYTEST_ARGS) \
	        -m "realtime and not alone and not campaign" \
	    && python -m pytest $(REALTIME_TESTS) -m "alone and not campaign"

# The repetitions and variants of what `make test` checks once (20 SIGINT stops of the stack,
# the driver's tests against the Python reference MCU too, every kind of link gap during a
# slip, the firmware's full cycle): serial, as real-time tests need. CI runs it after make test.
test-campaign: setup
	$(ENV) && python -m pytest tests -m campaign

# The numerical tests again as other x86-64 CPUs would run them: numpy's SIMD dispatch, numba's
# code generation and OpenBLAS's kernels limited to x86-64-v3 (AVX2 + FMA, no AVX-512: the Zen 3
# machines of this kind) and to x86-64-v2 (no AVX, no FMA). A tolerance that holds only on the
# CPU it was written on fails here (docs/design/numerics.md). CI runs it after `make test`.
# NUMBA_CPU_FEATURES is empty on purpose: with the CPU name alone numba keeps the host's
# features (AVX-512 on a Zen 4); empty, LLVM takes the named CPU's own. The same settings are
# rftgls_core/benchmarks/machine.py's CPU_TARGETS (`rftgls bench --cpu x86-64-v3`).
CPU_V3 := NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" NUMBA_CPU_NAME=znver3 \
    NUMBA_CPU_FEATURES= OPENBLAS_CORETYPE=Zen
CPU_V2 := NPY_DISABLE_CPU_FEATURES="X86_V3 X86_V4 AVX512_ICL AVX512_SPR" NUMBA_CPU_NAME=nehalem \
    NUMBA_CPU_FEATURES= OPENBLAS_CORETYPE=Nehalem
NUMERIC_TESTS := tests/core tests/lab
test-cpus: setup
	$(ENV) && $(CPU_V3) python -m pytest $(NUMERIC_TESTS) $(PYTEST_ARGS) -m "not realtime" -q
	$(ENV) && $(CPU_V2) python -m pytest $(NUMERIC_TESTS) $(PYTEST_ARGS) -m "not realtime" -q

# `colcon test` as a ROS user runs it: each package alone (its test/ folder: its unit tests and
# linters), then `colcon test-result`, which fails on any failed or erroring test. A package
# that fails prints its failures (`colcon test-result --verbose`: each failed test's message,
# ending with what its inner run printed) before the run stops.
colcon-test: setup
	$(ENV) && cd $(WS) && for p in $(COLCON_PKGS); do \
	    AMENT_PREFIX_PATH=$(CURDIR)/$(VENV):$$AMENT_PREFIX_PATH colcon test --packages-select $$p \
	        --return-code-on-test-failure --event-handlers console_direct- \
	        || { colcon test-result --verbose; exit 1; }; done \
	    && colcon test-result --all

# ruff (lint + import order) on every package and the tests; mypy on the core library.
lint: setup
	$(ENV) && ruff check src tests tools && mypy

bench: setup
	$(ENV) && rftgls bench

# Refresh the lock (after changing requirements/requirements.txt, or to take new releases):
# resolve requirements.txt in a scratch venv, freeze the exact versions (constraints.txt),
# then download those files, hash them, record the extras anything asks for, check that every
# requirement is covered, and write lock.txt (tools/lock.py). Then `make test`.
LOCKENV := /tmp/rftgls-lock
lock:
	rm -rf $(LOCKENV) && $(PY) -m venv $(LOCKENV)
	$(LOCKENV)/bin/pip install -q -r requirements/requirements.txt
	$(LOCKENV)/bin/pip install -q --no-deps --no-build-isolation $(foreach p,$(PKGS),src/$(p))
	$(LOCKENV)/bin/pip freeze | grep -vE "^([a-z_]+_(msgs|interfaces|srvs)|rosidl_[a-z_]+|rclpy|rcutils|rmw_dds_common|rftgls_core|rftgls_ros|minirquad_driver)==" > requirements/constraints.txt
	$(LOCKENV)/bin/python tools/lock.py write

clean:
	rm -rf $(VENV) $(WS)/build $(WS)/install $(WS)/log out $(FIRMWARE)/build
