"""A page in Debian's chromium driven by Playwright, for the tests that open the HTML the
workbench writes (Playwright's own browser download is not available here: the Makefile's
install rule puts chromium in place)."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest


@contextmanager
def chromium_page(path: Path, viewport: dict[str, int]) -> Iterator[tuple[Any, list[str], list[str]]]:
    """(page, console and page errors, requested URLs) with ``path`` loaded; the browser closes after."""
    chromium = shutil.which("chromium")
    assert chromium, "Debian's chromium is missing: `make install` installs it"
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is in the test extras: `make install`")
    errors: list[str] = []
    requests: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        view = browser.new_page(viewport=viewport)
        view.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        view.on("pageerror", lambda e: errors.append(str(e)))
        view.on("request", lambda r: requests.append(r.url))
        view.goto(path.as_uri())
        view.wait_for_load_state("load")
        try:
            yield view, errors, requests
        finally:
            browser.close()


def wait_until(view: Any, expression: str, timeout_s: float = 60.0) -> None:
    """Poll ``expression`` in the page until it is true. (Playwright's wait_for_function would
    compile it inside the page, which the report's Content-Security-Policy refuses: no eval.)
    The timeout only ends a hung page; nothing is judged by the time taken."""
    waited = 0.0
    while not view.evaluate(expression):
        assert waited < timeout_s, f"the page never met {expression!r} ({timeout_s:g} s)"
        view.wait_for_timeout(50)
        waited += 0.05
