"""Analytic measures for testing the study machinery (loaded via PARASYNTH_PLUGINS)."""

import os
import time

from parasynth.measures.objectives import OBJECTIVES, register

if "test_quadratic" not in OBJECTIVES:

    @register("test_quadratic", unit="m^2", sense="maximize", cost="cheap", settings={"delay": "float"})
    def test_quadratic(mech, delay: float = 0.0):
        """-(L - 0.2)^2 - (R - 0.14)^2 for the 5pus_upu link length L and slider radius R:
        maximum 0 at L = 0.2 m, R = 0.14 m."""
        if delay:
            time.sleep(delay)
        p = mech.params
        return -((p.link_length - 0.2) ** 2) - (p.slider_radius - 0.14) ** 2

    @register("test_link_length", unit="m", kind="length", sense="minimize", cost="cheap")
    def test_link_length(mech):
        """The link length (m), to test design constraints."""
        return mech.params.link_length

    @register("test_two", unit="m", kind="length", sense="minimize", cost="cheap")
    def test_two(mech):
        """L + 2 R, a second objective conflicting with test_quadratic near its optimum."""
        return mech.params.link_length + 2 * mech.params.slider_radius

    @register("test_fail_above", unit="m", kind="length", sense="minimize", cost="cheap")
    def test_fail_above(mech):
        """Raises for L > 0.21 m (a failing design)."""
        if mech.params.link_length > 0.21:
            raise RuntimeError("deliberate failure for L > 0.21 m")
        return mech.params.link_length

    if os.environ.get("PARASYNTH_TEST_MARKER"):
        open(os.environ["PARASYNTH_TEST_MARKER"], "a").close()
