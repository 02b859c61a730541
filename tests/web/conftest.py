"""Fixtures of the browser-viewer tests: one headless Chromium per module, and the scenes."""

from __future__ import annotations

import pytest

from tests.web.browser import console_log, start_chromium, unavailable_reason


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium (Selenium); skips, saying why, when it cannot be started here."""
    reason = unavailable_reason()
    if reason:
        pytest.skip(reason)
    driver = start_chromium()
    try:
        yield driver
    finally:
        log = console_log(driver)
        driver.quit()
        errors = [line for line in log if "SEVERE" in line and "favicon" not in line]
        if errors:  # a page error fails loudly, not as a later timeout
            print("browser console errors:", *errors, sep="\n  ")
