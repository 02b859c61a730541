"""Headless Chromium for the browser-viewer tests and benchmark: Debian's chromium and
chromium-driver (scripts/system-deps.sh installs them), driven by Selenium with the driver's
explicit path and Selenium Manager kept offline, so nothing downloads a browser build.

Software WebGL 2 comes from SwiftShader through ANGLE (``--use-angle=swiftshader``).
"""

from __future__ import annotations

import base64
import io
import os
import shutil
import time
from pathlib import Path

import numpy as np

CHROMIUM_PATHS = ("/usr/bin/chromium", "/usr/bin/chromium-browser")
DRIVER_PATHS = ("/usr/bin/chromedriver",)
CHROMIUM_FLAGS = (
    "--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--disable-extensions",
    "--no-first-run", "--window-size=1100,800", "--force-device-scale-factor=1",
)


def _first(paths) -> str | None:
    for path in paths:
        if Path(path).is_file() and os.access(path, os.X_OK):
            return path
    return None


def find_browser() -> tuple[str, str] | None:
    """(chromium, chromedriver) paths, or None when either is missing."""
    chromium = _first(CHROMIUM_PATHS) or shutil.which("chromium")
    driver = _first(DRIVER_PATHS) or shutil.which("chromedriver")
    return (chromium, driver) if chromium and driver else None


def unavailable_reason() -> str | None:
    """Why the browser tests cannot run here, or None when they can."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[dev]')"
    if find_browser() is None:
        return ("Debian's chromium and chromium-driver are not installed (scripts/system-deps.sh "
                "installs them when run as root with apt-get)")
    return None


def start_chromium():
    """A Selenium WebDriver on headless Chromium with software WebGL."""
    os.environ["SE_OFFLINE"] = "true"  # Selenium Manager must never fetch a driver or browser
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    chromium, driver = find_browser()
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    browser = webdriver.Chrome(service=Service(driver), options=options)
    browser.set_script_timeout(300)
    return browser


def viewer_state(browser) -> dict | None:
    """``window.csgsViewer.state`` of the page, without the selection mask."""
    return browser.execute_script(
        "const v = window.csgsViewer; if (!v) return null;"
        "const s = {...v.state}; if (s.selection) s.selection = {...s.selection, mask: null};"
        "return s;")


def wait_for_state(browser, done, timeout: float = 240.0, poll: float = 0.2) -> dict:
    """Poll the page state until ``done(state)`` holds; returns that state.

    Raises:
        TimeoutError: with the last state and the browser's console log.
    """
    deadline = time.monotonic() + timeout
    state = None
    while time.monotonic() < deadline:
        state = viewer_state(browser)
        if state is not None and done(state):
            return state
        time.sleep(poll)
    raise TimeoutError(f"page state {state}; console: {console_log(browser)}")


def console_log(browser) -> list[str]:
    """The browser console's messages so far."""
    try:
        return [entry["message"] for entry in browser.get_log("browser")]
    except Exception:  # noqa: BLE001 - only for error messages
        return []


def camera_json(camera) -> dict:
    """A project Camera as the page's setCamera takes it."""
    return {"width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy,
            "cx": camera.cx, "cy": camera.cy,
            "world_to_camera": np.asarray(camera.world_to_camera, float).tolist(),
            "near_plane": camera.near_plane}


def show_camera(browser, camera) -> np.ndarray:
    """Point the page at ``camera``, wait for a frame drawn with the splats sorted for it, and
    return the canvas as (H, W, 3) float64 in [0, 1]."""
    data_url = browser.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "window.csgsViewer.setCamera(arguments[0]);"
        "window.csgsViewer.frameDrawn().then(() => done(window.csgsViewer.capture()));",
        camera_json(camera))
    return png_pixels(base64.b64decode(data_url.split(",", 1)[1]))


def png_pixels(png: bytes) -> np.ndarray:
    """(H, W, 3) float64 in [0, 1] of PNG bytes."""
    from PIL import Image

    with Image.open(io.BytesIO(png)) as image:
        return np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of two images in [0, 1]."""
    mse = float(np.mean((np.asarray(a, float) - np.asarray(b, float)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)
