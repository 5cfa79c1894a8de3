# The two commands of the README:
#   make demo   run the main job (the paper's experiment in simulation)
#   make test   run the test suite
# Both set everything up first on a fresh Debian 12 / Python 3.11 machine: system packages,
# .venv with the pinned Python dependencies, and a colcon build into build/ and install/.
# Where /opt/ros/jazzy exists it is used instead of the ROS 2 wheels from PyPI.

SHELL := /bin/bash
.DEFAULT_GOAL := help

PYTHON ?= python3
VENV := .venv
ROS_SETUP := /opt/ros/jazzy/setup.bash
WS := tools/workspace-env
PIP := $(VENV)/bin/python -m pip --disable-pip-version-check
PIP_QUIET := 2>&1 | { grep -v -e 'is ignored: it is neither a file nor a directory' -e '^\s*$$' || true; }
PACKAGES := $(patsubst %/package.xml,%,$(wildcard */package.xml))
PACKAGE_FILES := $(shell find $(PACKAGES) -type f -not -path '*/__pycache__/*' -not -name '*.pyc' 2>/dev/null)

ifneq ($(wildcard $(ROS_SETUP)),)
  ROS_MODE := system
  VENV_FLAGS := --system-site-packages
  REQUIREMENTS := requirements/system-ros.txt
else
  ROS_MODE := wheels
  VENV_FLAGS :=
  REQUIREMENTS := requirements/lock.txt
endif

.PHONY: help demo test build setup system-deps lint lock clean distclean

help:
	@echo "make demo    run the main job (sets everything up first)"
	@echo "make test    run the test suite (sets everything up first)"
	@echo "make build   set up and build only"
	@echo "make lint    ruff over the repository"
	@echo "make lock    regenerate requirements/lock.txt from requirements/*.in"
	@echo "make clean   remove build/ install/ log/;  make distclean also removes .venv"

demo: build
	$(WS) ros2 run tiling_sim experiment --structure config/structures/paper_14.yaml --report reports/paper_14

test: build
	$(WS) python -m pytest

build: install/.built

setup: $(VENV)/.installed

system-deps:
	@tools/install-system-deps

$(VENV)/.installed: $(REQUIREMENTS) requirements/no-deps.in | system-deps
	@echo "Setting up $(VENV) ($(ROS_MODE) ROS 2) from $(REQUIREMENTS)"
	@test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV_FLAGS) $(VENV)
	@set -o pipefail; $(PIP) install --quiet --no-deps -r $(REQUIREMENTS) $(PIP_QUIET)
	@set -o pipefail; $(PIP) install --quiet --no-deps -r requirements/no-deps.in $(PIP_QUIET)
	@if [ "$(ROS_MODE)" = wheels ]; then ln -sf ../../tools/ros2 $(VENV)/bin/ros2; fi
	@touch $@

install/.built: $(VENV)/.installed $(PACKAGE_FILES) | system-deps
	@echo "Building the workspace: $(PACKAGES)"
	@set -o pipefail; $(WS) colcon --log-base log build --symlink-install \
	  --event-handlers console_direct- 2>&1 \
	  | { grep -v -e "^Starting >>>" -e "^Finished <<<" -e "doesn.t contain any .local_setup" || true; }
	@touch $@

lint: setup
	@$(PIP) install --quiet ruff==0.14.4 $(PIP_QUIET)
	$(VENV)/bin/ruff check .

lock:
	tools/lock-requirements

clean:
	rm -rf build install log

distclean: clean
	rm -rf $(VENV)
