"""tests/_optional.py: a missing optional tool skips with the reason, or fails when its
PARASYNTH_REQUIRE_* variable is set (as .ci/run sets them)."""

import pytest

import _optional
from _optional import BROWSER, DASHBOARD, SIMULATORS, find_browser, import_or_skip


@pytest.mark.parametrize("var", [SIMULATORS, BROWSER, DASHBOARD])
def test_a_missing_module_skips_or_fails_when_required(monkeypatch, var):
    monkeypatch.delenv(var, raising=False)
    with pytest.raises(pytest.skip.Exception, match="pip install not-a-package"):
        import_or_skip("parasynth_no_such_module", var, "not-a-package")
    monkeypatch.setenv(var, "0")  # 0 or empty: not required
    with pytest.raises(pytest.skip.Exception):
        import_or_skip("parasynth_no_such_module", var)
    monkeypatch.setenv(var, "1")
    with pytest.raises(pytest.fail.Exception, match=f"{var} is set"):
        import_or_skip("parasynth_no_such_module", var)
    assert import_or_skip("json", var).dumps([]) == "[]"


def test_a_missing_browser_or_driver_skips_or_fails_when_required(monkeypatch, tmp_path):
    monkeypatch.setattr(_optional.shutil, "which", lambda name: None)
    monkeypatch.setattr(_optional, "CHROMEDRIVER", str(tmp_path / "none"))
    monkeypatch.delenv(BROWSER, raising=False)
    with pytest.raises(pytest.skip.Exception, match="apt-get install chromium"):
        find_browser()
    monkeypatch.setenv(BROWSER, "1")
    with pytest.raises(pytest.fail.Exception, match="apt-get install chromium"):
        find_browser()
    fake = tmp_path / "chromium"
    fake.write_text("")
    monkeypatch.setattr(_optional.shutil, "which", lambda name: str(fake) if name == "chromium" else None)
    with pytest.raises(pytest.fail.Exception, match="chromium-driver"):
        find_browser()
