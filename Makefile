# tactile_sensor workspace. On a machine without ROS everything of one distribution lives in
# .venv/DISTRO, build/DISTRO and install/DISTRO. DISTRO=jazzy (default, the LTS) or kilted.
SHELL := /bin/bash
.DEFAULT_GOAL := help
DISTRO ?= jazzy
export DISTRO

.PHONY: help setup build test test-fast test-ros2 lint docs firmware demo demo-gripper demo-rate demo-wrench demo-ambient demo-lift demo-bend bench bench-publish bench-report clean

help:  ## list the targets (each takes DISTRO=jazzy|kilted; default jazzy)
	@grep -E '^[a-z0-9-]+:.*##' $(MAKEFILE_LIST) | sed 's/:.*## /\t/'

setup:  ## venv + pinned ROS 2 wheels of DISTRO + colcon build (idempotent)
	@bash scripts/setup.sh

build: setup  ## alias of setup

test:  ## setup if needed, ruff, the whole suite with ROS isolated per run (what CI runs)
	@bash scripts/test.sh

test-fast:  ## ruff and every test that starts no process (a few minutes; before each commit)
	@TACTILE_TEST_FAST=1 bash scripts/test.sh -m "not slow"

test-ros2:  ## the tests that need a sourced ROS 2 (ros2 launch, the ros2 CLI, launch_ros), which the wheels path skips; refuses in one sentence without one
	@python3 tactile_sensor/test/ros2_tools.py && bash scripts/test.sh -m ros2_tools

docs: setup  ## the ROS interface reference from the code, the pages' figures from benchmarks/results, then docs/ to HTML (build/docs/html), warnings as errors
	@. scripts/env.sh && python -m tactile_sensor.nodes.interface_reference docs/reference >/dev/null \
		&& MPLBACKEND=Agg python benchmarks/docs_figures.py \
		&& sphinx-build -W --keep-going -q -b html docs build/docs/html \
		&& echo "docs: build/docs/html/index.html"

firmware:  ## cross-compile the ADC sketch for Uno, Mega, Leonardo, 8-channel Nano, modulated Uno and 8-channel Nano (avr-g++, -Werror), print sizes
	@bash firmware/build-avr.sh

lint: setup  ## ruff only
	@. scripts/env.sh && ruff check .

demo: setup  ## bench presses at 0.1, 1 and 10 mm/s on mock hardware, recorded and analysed (about a minute)
	@bash scripts/demo.sh bench

demo-gripper: setup  ## grasp the rod, hold, release on mock hardware
	@bash scripts/demo.sh gripper

demo-rate: setup  ## fit force across speeds on 'speeds', check it on unseen speeds with holds
	@bash scripts/demo.sh rate

demo-wrench: setup  ## press, shear, tilt and twist on the 8-module layout; print the six errors
	@bash scripts/demo.sh wrench

demo-ambient: setup  ## force error in the dark, under light and drift: today's driver beside each kind of module
	@bash scripts/demo.sh ambient

demo-lift: setup  ## lift objects, double their load: slip of a fixed grasp beside the adaptive hold
	@bash scripts/demo.sh lift

demo-bend: setup  ## bend a soft finger: joint angle RMSE, lag and hysteresis against the truth, with and without a tip contact
	@bash scripts/demo.sh bend

bench: setup  ## every benchmark in benchmarks/: prints its figures, writes build/benchmarks/results/
	@. scripts/env.sh && skipped=""; for b in benchmarks/bench_*.py; do echo "== $$b"; \
	  python "$$b"; rc=$$?; [ $$rc -eq 77 ] && skipped="$$skipped $$b"; \
	  [ $$rc -eq 0 ] || [ $$rc -eq 77 ] || exit $$rc; done; \
	  [ -z "$$skipped" ] || echo "bench: skipped (they need ros2 launch):$$skipped"

bench-publish:  ## at a clean checkout: copy build/benchmarks/results/ to benchmarks/results/, render the page
	@python3 benchmarks/publish.py

bench-report:  ## render docs/benchmarks.md from the published benchmarks/results/*.json
	@python3 benchmarks/report.py

clean:  ## remove the build products of DISTRO (keeps its venv)
	rm -rf build/$(DISTRO) install/$(DISTRO) log/$(DISTRO) build/docs .cache demo-out
