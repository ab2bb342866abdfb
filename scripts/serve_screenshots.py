"""Screenshots of the pages of ``dancekit serve`` for the docs: docs/serve_dance.png, serve_compose.png,
serve_models.png (PNG, quantised to stay small).

Starts a server on 127.0.0.1 (one worker, a temporary cache), drives Debian's Chromium with Playwright's
Python package (``executable_path``; no browser download) through a dance of the demo tune and a compose of
that dance, and saves each page. Run: ``python scripts/serve_screenshots.py [--chromium /usr/bin/chromium]``.
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--autoplay-policy=no-user-gesture-required", "--mute-audio"]


def save(png: bytes, path: Path, colors: int = 96) -> None:
    from PIL import Image

    img = Image.open(io.BytesIO(png)).convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT)
    img.save(path, optimize=True)
    print(f"{path}: {path.stat().st_size / 1e3:.0f} KB")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--out", default=str(ROOT / "docs"))
    args = parser.parse_args()
    from _serve import Server
    from playwright.sync_api import sync_playwright

    out = Path(args.out)
    with tempfile.TemporaryDirectory() as tmp:
        srv = Server(Path(tmp) / "cache", "--workers", "1")
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=args.chromium, headless=True, args=FLAGS)
                page = browser.new_page(viewport={"width": 1000, "height": 980}, accept_downloads=True)
                page.goto(srv.url + "/")
                page.wait_for_selector("#model option", state="attached")
                page.click("#demo")
                page.fill("#seeds", "0-1")
                page.click("#go")
                page.wait_for_selector("#downloads a[data-name$='.glb']", timeout=300_000)
                page.frame_locator("#frame").locator("#dk-play").click()
                time.sleep(2.5)
                save(page.screenshot(full_page=True), out / "serve_dance.png")
                with page.expect_download() as info:
                    page.click("#downloads a[data-name='ode_to_joy_seed0.npz']")
                npz = Path(tmp) / "ode_to_joy.npz"
                info.value.save_as(npz)
                page.goto(srv.url + "/compose")
                page.wait_for_selector("#model option", state="attached")
                page.set_input_files("#file", str(npz))
                page.click("#go")
                page.wait_for_selector("#downloads a", timeout=300_000)
                page.frame_locator("#frame").locator("#dk-play").click()
                time.sleep(2.0)
                save(page.screenshot(full_page=True), out / "serve_compose.png")
                page.set_viewport_size({"width": 1000, "height": 900})
                page.goto(srv.url + "/models")
                page.wait_for_selector("#cards .card")
                save(page.screenshot(), out / "serve_models.png")
                browser.close()
        finally:
            srv.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
