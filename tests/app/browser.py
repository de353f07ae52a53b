"""Helpers for driving the app in headless Chromium (Playwright, software WebGL).

Reading pixels: viser's WebGL canvas keeps its drawing buffer, so the page can
copy it into a small 2-D canvas and count colours there (fast), instead of taking
Playwright screenshots (seconds per frame under software rendering).
"""

from __future__ import annotations

import base64
import contextlib
import io
import re
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    "--disable-dev-shm-usage", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-quic",
]
VIEWPORT = {"width": 1280, "height": 800}
#: Part of the canvas left of the control panel and below the top bar (fractions).
SCENE = (0.02, 0.12, 0.62, 0.95)

# Copy the largest canvas (the three.js one) into a w x h 2-D canvas and return
# its RGBA bytes as base64; transparent pixels are the page background (white).
_GRAB_JS = r"""
([x0, y0, x1, y1, w, h]) => {
  const cs = [...document.querySelectorAll('canvas')];
  let src = null;
  for (const c of cs) if (!src || c.width * c.height > src.width * src.height) src = c;
  if (!src || !src.width) return null;
  const t = document.createElement('canvas'); t.width = w; t.height = h;
  const g = t.getContext('2d', {willReadFrequently: true});
  g.drawImage(src, x0 * src.width, y0 * src.height, (x1 - x0) * src.width,
              (y1 - y0) * src.height, 0, 0, w, h);
  const d = g.getImageData(0, 0, w, h).data;
  let s = ''; for (let i = 0; i < d.length; i++) s += String.fromCharCode(d[i]);
  return btoa(s);
}
"""

# Fraction of saturated (coloured, not white/grey) pixels in the scene region.
_COLOURED_JS = r"""
([grab, region]) => {
  const b = eval(grab)(region); if (!b) return 0;
  const s = atob(b); let n = 0;
  for (let i = 0; i < s.length; i += 4) {
    if (s.charCodeAt(i + 3) < 16) continue;
    const r = s.charCodeAt(i), g = s.charCodeAt(i + 1), bl = s.charCodeAt(i + 2);
    if (Math.max(r, g, bl) - Math.min(r, g, bl) > 40) n++;
  }
  return n / (s.length / 4);
}
"""


def scene_pixels(page, w: int = 192, h: int = 160, region=SCENE) -> np.ndarray:
    """RGB (h, w, 3) uint8 of the scene region, transparent -> white."""
    b64 = page.evaluate(_GRAB_JS, [*region, w, h])
    rgba = np.frombuffer(base64.b64decode(b64), dtype=np.uint8).reshape(h, w, 4).astype(float)
    a = rgba[..., 3:4] / 255.0
    return np.round(rgba[..., :3] * a + 255.0 * (1 - a)).astype(np.uint8)


def coloured_mask(img: np.ndarray) -> np.ndarray:
    """Pixels with a clear hue (point colours), not white, grey or black."""
    i = img.astype(int)
    return (i.max(axis=2) - i.min(axis=2)) > 40


def wait_coloured(page, min_fraction: float = 0.05, timeout: float = 90.0) -> None:
    """Wait until enough of the scene shows coloured points."""
    page.wait_for_function(
        "([js, grab, region, f]) => eval(js)([grab, region]) >= f",
        arg=[_COLOURED_JS, _GRAB_JS, [*SCENE, 96, 80], min_fraction],
        polling=200, timeout=timeout * 1000,
    )


def wait_until(predicate, timeout: float = 30.0, what: str = "condition"):
    end = time.time() + timeout
    while time.time() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise TimeoutError(f"timed out waiting for {what}")


def wait_pixels(page, predicate, timeout: float = 60.0, what: str = "pixels"):
    """Poll the scene image until ``predicate(img)`` is true; returns the image."""
    end = time.time() + timeout
    while time.time() < end:
        img = scene_pixels(page)
        if predicate(img):
            return img
        time.sleep(0.3)
    raise TimeoutError(f"timed out waiting for {what}")


def control(page, label: str):
    """The element a GUI row's <label> points at (viser ids it by the handle uuid)."""
    lab = page.locator("label", has_text=re.compile(f"^{re.escape(label)}$")).first
    return page.locator(f'[id="{lab.get_attribute("for")}"]')


def text_input(page, label: str):
    """The <input> of the text field labelled ``label`` (Mantine gives it its own id)."""
    lab = page.locator("label", has_text=re.compile(f"^{re.escape(label)}$")).first
    return lab.locator("xpath=../../..").locator("input").first


def choose(page, label: str, option: str) -> None:
    """Pick ``option`` in the dropdown labelled ``label``."""
    control(page, label).click()
    page.get_by_role("option", name=option, exact=True).click()


def type_number(page, label: str, value: str) -> None:
    """Type into the number box of a slider (never arrow keys: they move the camera)."""
    box = control(page, label).locator("xpath=..").locator("input.mantine-NumberInput-input")
    box.fill(value)
    box.press("Enter")


def hide_toasts(page) -> None:
    """Hide notifications (the software-WebGL warning covers the scene)."""
    page.add_style_tag(content=".mantine-Notifications-root{display:none!important}")


def png(page) -> bytes:
    """PNG of the whole canvas (for a person to look at)."""
    url = page.evaluate("() => { let s = null; for (const c of document.querySelectorAll('canvas'))"
                        " if (!s || c.width * c.height > s.width * s.height) s = c;"
                        " return s.toDataURL('image/png'); }")
    return base64.b64decode(url.split(",", 1)[1])


def to_array(png_bytes: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png_bytes)).convert("RGB"))


#: The window size issue 13 measures the panels at.
WIDE = {"width": 1600, "height": 1000}

#: Widths of every visible plotly panel, px.
_PLOT_WIDTHS_JS = ("() => [...document.querySelectorAll('.js-plotly-plot')]"
                   ".filter(e => e.offsetParent !== null)"
                   ".map(e => e.getBoundingClientRect().width)")


def plot_widths(page) -> list[float]:
    """Widths (px) of the plotly panels shown now (hidden tabs left out)."""
    return [float(w) for w in page.evaluate(_PLOT_WIDTHS_JS)]


def canvas_rgba(page) -> np.ndarray:
    """RGBA (h, w, 4) uint8 of the whole 3-D canvas (alpha 0: the page background)."""
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png(page))).convert("RGBA"))


def drawn_colour_share(rgba: np.ndarray, lut: np.ndarray, tol: int = 24) -> tuple[float, int]:
    """Of the drawn pixels whose colour is one of the map's (within ``tol``, summed
    over channels, of an entry of ``lut``), the largest share on one entry, and how
    many such pixels there are. Background (transparent), grey no-value points and
    overlays in other colours are left out."""
    px = rgba[rgba[..., 3] > 250][:, :3].astype(int)
    table = np.asarray(lut, dtype=int)
    best = np.empty(len(px), dtype=int)
    dist = np.empty(len(px), dtype=int)
    for start in range(0, len(px), 20_000):
        d = np.abs(px[start:start + 20_000, None, :] - table[None, :, :]).sum(axis=2)
        best[start:start + 20_000] = d.argmin(axis=1)
        dist[start:start + 20_000] = d.min(axis=1)
    on_map = best[dist <= tol]
    if on_map.size == 0:
        return 0.0, 0
    return float(np.bincount(on_map).max()) / on_map.size, int(on_map.size)


@contextlib.contextmanager
def app_page(chromium, app, *, viewport: dict[str, int] = VIEWPORT,
             coloured: float = 0.05, timeout: float = 90.0, step_timeout_ms: int = 30_000,
             **context: Any) -> Iterator[Any]:
    """A page on ``app`` (on its viser server), once its cloud is drawn (``coloured``
    share of the scene within ``timeout`` s) and its toasts hidden; on leaving, the
    page's JavaScript errors fail the test, and the app and its server are stopped."""
    try:
        ctx = chromium.new_context(viewport=viewport, **context)
        ctx.set_default_timeout(step_timeout_ms)
        page = ctx.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        try:
            page.goto(f"http://127.0.0.1:{app.server.get_port()}/?fixedDpr=1&hideViserLogo")
            wait_coloured(page, coloured, timeout=timeout)
            hide_toasts(page)
            yield page
        finally:
            ctx.close()
        assert not errors, errors
    finally:
        app.stop()
        app.server.stop()
