"""The browser tests' one harness (a pytest plugin, tests/conftest.py loads it): Debian's
chromium driven by Playwright, one browser per module, pages that fail their test on any
console error or uncaught exception, and where screenshots go."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
needs_chromium = pytest.mark.skipif(not Path(CHROMIUM).exists(), reason=f"needs Debian's chromium at {CHROMIUM}")


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    from playwright.sync_api import sync_playwright  # only where a test asks for a browser

    with sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("chromium-profile")), executable_path=CHROMIUM, headless=True,
            args=CHROMIUM_ARGS, viewport={"width": 1400, "height": 1000})
        yield context
        context.close()


@pytest.fixture
def screenshots(tmp_path):
    """Where a test saves what it looked at: $DEEPPHY_SCREENSHOTS to keep them, else tmp."""
    out = Path(os.environ.get("DEEPPHY_SCREENSHOTS", tmp_path))
    out.mkdir(parents=True, exist_ok=True)
    return out


@pytest.fixture
def open_page(browser):
    """Opens a URL; console errors and uncaught exceptions fail the test."""
    pages, errors = [], []

    def opener(url):
        page = browser.new_page()
        page.on("console", lambda m: errors.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
        page.goto(url)
        pages.append(page)
        return page

    yield opener
    for page in pages:
        if not page.is_closed():
            page.close()
    assert not errors, errors
