"""Take the README screenshot of the app on a demo cloud (headless Chromium).

    PYTHONPATH=. python scripts/screenshot_app.py [--demo outcrop] [--out docs/screenshot.png]
        [--max-points 400000] [--grid G] [--model odr]

Needs Debian's ``chromium`` (/usr/bin/chromium) and the ``playwright`` Python
package (no ``playwright install``). Software WebGL is slow: fewer display points
give a quicker, equally readable picture.
"""

from __future__ import annotations

import argparse
import time

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader", "--disable-dev-shm-usage", "--no-first-run"]

# True once enough of the 3-D canvas shows coloured (saturated) pixels.
READY_JS = r"""
() => {
  let src = null;
  for (const c of document.querySelectorAll('canvas'))
    if (!src || c.width * c.height > src.width * src.height) src = c;
  if (!src || !src.width) return false;
  const t = document.createElement('canvas'); t.width = 120; t.height = 80;
  const g = t.getContext('2d', {willReadFrequently: true});
  g.drawImage(src, 0, 0, 0.6 * src.width, src.height, 0, 0, 120, 80);
  const d = g.getImageData(0, 0, 120, 80).data; let n = 0;
  for (let i = 0; i < d.length; i += 4)
    if (d[i + 3] > 16 && Math.max(d[i], d[i+1], d[i+2]) - Math.min(d[i], d[i+1], d[i+2]) > 40) n++;
  return n / (d.length / 4) > 0.05;
}
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--demo", default="outcrop")
    ap.add_argument("--out", default="docs/screenshot.png")
    ap.add_argument("--max-points", type=int, default=400_000)
    ap.add_argument("--grid", type=float, default=None,
                    help="grid size in metres (default: the cloud's, from its point spacing)")
    ap.add_argument("--model", default="odr", choices=("odr", "ols", "hybrid", "e_ols"))
    args = ap.parse_args()

    import viser
    from playwright.sync_api import sync_playwright

    from rough_viewer.app.cloud import grid_presets
    from rough_viewer.app.server import build_app
    from rough_viewer.app.settings import MapSettings
    from rough_viewer.synthetic import demos

    cloud = demos.load_demo(args.demo)
    cell = args.grid if args.grid is not None else grid_presets(cloud)[-1]
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, cloud, max_display=args.max_points,
                    settings=MapSettings(cell_size=cell, model=args.model),
                    prefetch=False)
    app.wait_idle(None)
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            page = browser.new_page(viewport={"width": 1600, "height": 1000})
            page.goto(f"http://127.0.0.1:{server.get_port()}/?fixedDpr=1&hideViserLogo")
            page.wait_for_function(READY_JS, polling=500, timeout=240_000)
            page.add_style_tag(content=".mantine-Notifications-root{display:none!important}")
            time.sleep(2.0)  # let the panel plots settle
            page.screenshot(path=args.out, timeout=240_000)
            browser.close()
    finally:
        app.stop()
        server.stop()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
