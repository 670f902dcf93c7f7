"""Optional tools of the tests: a missing one skips the tests that need it, with the reason,
unless its environment variable is set, and then it fails them (``.ci/run`` sets all three).

* ``PARASYNTH_REQUIRE_SIMULATORS``: MuJoCo (``mujoco``) and Pinocchio (``pin``), the export checks;
* ``PARASYNTH_REQUIRE_BROWSER``: headless Chromium, its driver (Debian's ``chromium`` and
  ``chromium-driver``) and ``selenium``, the interactive report's checks;
* ``PARASYNTH_REQUIRE_DASHBOARD``: ``optuna-dashboard``, the check that it reads a run's storage.

The Python packages are in the ``test`` extra; the browser comes from the system package manager.
Nothing here downloads a browser or a driver.
"""

from __future__ import annotations

import importlib
import os
import shutil
from pathlib import Path

import pytest

SIMULATORS = "PARASYNTH_REQUIRE_SIMULATORS"
BROWSER = "PARASYNTH_REQUIRE_BROWSER"
DASHBOARD = "PARASYNTH_REQUIRE_DASHBOARD"

#: Where Debian's chromium-driver puts the driver (also searched on PATH).
CHROMEDRIVER = "/usr/bin/chromedriver"


def required(env_var: str) -> bool:
    """Is the tool of ``env_var`` required (the variable set to anything but empty or 0)?"""
    return os.environ.get(env_var, "") not in ("", "0")


def missing(reason: str, env_var: str):
    """Skip with ``reason``; fail instead when ``env_var`` requires the tool."""
    if required(env_var):
        pytest.fail(f"{reason} ({env_var} is set: the tool is required here)", pytrace=False)
    pytest.skip(reason, allow_module_level=True)  # at import time or in a test


def import_or_skip(module: str, env_var: str, package: str | None = None):
    """``module`` imported, or a skip naming the package to install (a failure when ``env_var``
    is set)."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        missing(f"{module} is not installed (pip install {package or module}; in the test extra): {e}", env_var)


def find_browser(env_var: str = BROWSER) -> tuple[str, str]:
    """The paths of a headless-capable Chromium and of its chromedriver, or a skip saying which is
    missing (a failure when ``env_var`` is set)."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if browser is None:
        missing("headless Chromium is not installed (apt-get install chromium)", env_var)
    driver = CHROMEDRIVER if Path(CHROMEDRIVER).is_file() else shutil.which("chromedriver")
    if driver is None:
        missing("chromedriver is not installed (apt-get install chromium-driver)", env_var)
    return browser, driver
