"""Headless Chromium for the report tests: Debian's /usr/bin/chromium driven by playwright.

`make test` installs the browser when it is missing (see the Makefile's `browser` step), so
CI runs these tests. Elsewhere a missing browser skips them; under CI (`CI=true`) it fails.
"""

import os
from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")


def _unavailable(reason: str):
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason} (CI=true: the report test must run; `make test` installs the browser)")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def chromium():
    if not CHROMIUM.exists():
        _unavailable(f"{CHROMIUM} missing: apt-get install -y chromium")
    try:
        from playwright.sync_api import sync_playwright
    except ModuleNotFoundError:
        _unavailable("playwright missing: pip install -e '.[test]'")
    with sync_playwright() as p:
        # --no-sandbox: CI runs as root, where Chromium refuses its sandbox.
        browser = p.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox"])
        yield browser
        browser.close()


@pytest.fixture
def open_offline(chromium):
    """open_offline(path) -> (page, urls requested). Any request that is not the file itself
    or an inline data: URI is recorded and aborted, so a page that needs the network shows it."""
    context = chromium.new_context(offline=True, viewport={"width": 1400, "height": 1000})  # pages must fit 1400 px
    page = context.new_page()
    requested = []

    def route(r):
        requested.append(r.request.url)
        if r.request.url.startswith(("file:", "data:")):
            r.continue_()
        else:
            r.abort()

    page.route("**/*", route)

    def open_(path):
        page.goto(Path(path).resolve().as_uri())
        page.wait_for_load_state("load")
        return page, requested

    yield open_
    context.close()


def horizontal_overflow(page) -> int:
    """Pixels the page is wider than the window (0: nothing needs a horizontal scroll)."""
    return page.evaluate("Math.max(document.documentElement.scrollWidth, document.body.scrollWidth) - window.innerWidth")


def images_loaded(page) -> list[int]:
    """naturalWidth of every <img> once it finished loading (0 = broken)."""
    return page.evaluate("Array.from(document.images).map(i => i.complete ? i.naturalWidth : 0)")
