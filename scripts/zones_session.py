"""Use the Zones tab as a user would, in headless Chromium, and save screenshots.

    PYTHONPATH=. python scripts/zones_session.py [--demo outcrop | --input FILE]
        [--grid 0.125] [--threshold 0.1] [--max-points 400000] [--out /tmp/zones-shots]

Opens the app, sets the grid and the Map tab's threshold, opens the Zones tab,
ticks "Show zones", clicks the largest zone on the rock, moves the tab's threshold
twice, and prints the zone count, the server's re-label times and its memory.
Screenshots: ``zones.png`` (the zones), ``selected.png`` (a zone clicked),
``panel.png`` (its numbers, the table and the stereonet). Needs Debian's
``chromium`` and the ``playwright`` package (no ``playwright install``).
"""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

import numpy as np

from tests.app import browser as b


def rss_mb() -> float:
    """Resident memory of this process (the server), MiB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--demo", default="outcrop")
    ap.add_argument("--input", help="a point-cloud file instead of the demo")
    ap.add_argument("--grid", type=float, default=0.125)
    ap.add_argument("--threshold", type=float, default=0.1)
    ap.add_argument("--max-points", type=int, default=400_000)
    ap.add_argument("--out", default="/tmp/zones-shots")
    args = ap.parse_args()

    import viser
    from playwright.sync_api import sync_playwright

    from rough_viewer.app.features.zones import ZonesFeature
    from rough_viewer.app.server import build_app
    from rough_viewer.app.settings import MapSettings
    from rough_viewer.io.load import load_points
    from rough_viewer.synthetic import demos
    from rough_viewer.visual import colormaps
    from rough_viewer.vocabulary import hex_to_rgb

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cloud = load_points(args.input) if args.input else demos.load_demo(args.demo)
    rss0 = rss_mb()
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, cloud, max_display=args.max_points, prefetch=False,
                    settings=MapSettings(cell_size=args.grid))
    app.wait_idle(None)
    m = app.feature(ZonesFeature)
    print(f"{cloud.source}: {cloud.n:,} points, {app.session.shown.loaded.n_display:,} shown, "
          f"grid {args.grid:g} m; server memory {rss0:.0f} -> {rss_mb():.0f} MiB after the map")
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=b.CHROMIUM, headless=True, args=b.ARGS)
            page = browser.new_page(viewport={"width": 1440, "height": 900})
            page.set_default_timeout(120_000)
            page.goto(f"http://127.0.0.1:{server.get_port()}/?fixedDpr=1&hideViserLogo")
            b.wait_coloured(page, 0.05, timeout=300)
            b.hide_toasts(page)
            b.type_number(page, "Threshold", f"{args.threshold:g}")
            b.wait_until(lambda: app.session.shown.settings.threshold == args.threshold
                         and not app.worker.busy, 120, "threshold")
            page.get_by_role("tab", name="Zones").click()
            before = b.scene_pixels(page)
            t0 = time.perf_counter()
            b.control(page, "Show zones").click()
            b.wait_until(lambda: m.zones is not None and not app.worker.busy, 300, "zones")
            print(f"zones on: {time.perf_counter() - t0:.2f} s until the table "
                  f"(first labelling {m.timings[-1]['colours_s']:.2f} s, labeller build "
                  f"{m.timings[-1]['basis_s']:.2f} s, table {m.timings[-1]['table_s']:.2f} s); "
                  f"memory {rss_mb():.0f} MiB")
            print(re.sub(r"[*\\]", "", m.status.content))
            b.wait_pixels(page, lambda im: np.abs(im.astype(int) - before).sum(axis=2).mean() > 5,
                          300, "zone colours")
            time.sleep(2.0)
            page.screenshot(path=str(out / "zones.png"), timeout=300_000)
            # click the largest zone on the rock
            img = b.to_array(b.png(page))
            h, w = img.shape[:2]
            target = np.asarray(hex_to_rgb(colormaps.zone_colour(1)))
            mask = np.abs(img.astype(int) - target).sum(axis=2) < 12
            mask[:, int(0.62 * w):] = False
            mask[: int(0.12 * h), :] = False
            ys, xs = np.nonzero(mask)
            if ys.size:
                k = int(np.argmin((ys - np.median(ys)) ** 2 + (xs - np.median(xs)) ** 2))
                page.mouse.click(int(xs[k]), int(ys[k]))
                b.wait_until(lambda: m.anchor is not None and not app.worker.busy, 120, "a selection")
                lab = m.labelling
                assert lab is not None
                zone = lab.zone_at(m.anchor)
                print(f"clicked zone {zone} ({int(np.count_nonzero(lab.labels == zone)):,} cells)")
                time.sleep(3.0)
                page.screenshot(path=str(out / "selected.png"), timeout=300_000)
            else:
                print("zone 1 is not on screen; no click")
            page.locator(".js-plotly-plot").last.scroll_into_view_if_needed()
            time.sleep(2.0)
            page.screenshot(path=str(out / "panel.png"), timeout=300_000)
            for thr in (args.threshold * 1.5, args.threshold * 0.75):
                n = len(m.timings)
                t0 = time.perf_counter()
                b.type_number(page, "Zone threshold", f"{thr:.2f}")
                b.wait_until(lambda n=n: len(m.timings) > n, 60, "re-label")
                t_col = m.timings[-1]["done"] - t0
                b.wait_until(lambda: not app.worker.busy, 120, "idle")
                rec = m.timings[-1]
                assert m.labelling is not None
                print(f"threshold {thr:.2f}: {m.labelling.n_zones:,} zones; typed -> zone colours "
                      f"{t_col:.2f} s (re-label {rec['label_s']:.3f} s, labels + colours "
                      f"{rec['colours_s']:.3f} s), table + stereonet {rec.get('table_s', 0):.2f} s")
            page.screenshot(path=str(out / "relabelled.png"), timeout=300_000)
            browser.close()
    finally:
        print(f"server memory at the end {rss_mb():.0f} MiB; zone cache "
              f"{m.cache.bytes / 2**20:.0f} MiB of {m.cache.budget / 2**20:.0f} MiB")
        app.stop()
        server.stop()


if __name__ == "__main__":
    main()
