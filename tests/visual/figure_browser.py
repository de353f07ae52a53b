"""Is a plotly figure legible? Measure its text in headless Chromium.

:func:`measure` reads the boxes of every text of one rendered plotly figure (any
``.js-plotly-plot`` element: a page of our own, the report or the viser app's
panels) and :func:`problems` lists what a reader would see as broken:

- text outside the figure (titles or labels cut at its edge);
- table text wider than its cell (plotly clips it: ``1.782e``, ``minimu``), or a
  row scrolled out of the table's visible area;
- overlaps between the title, axis titles, tick labels, subplot titles and the
  legend.
"""

from __future__ import annotations

from typing import Any

#: Box of every text of the plot inside ``root``, relative to its top-left corner.
MEASURE_JS = r"""
(root) => {
  const svg = root.querySelector('.main-svg');
  const W = svg.getBoundingClientRect();
  const box = (e) => { const r = e.getBoundingClientRect();
    return {x0: r.left - W.left, x1: r.right - W.left, y0: r.top - W.top, y1: r.bottom - W.top}; };
  const kind = (t) => {
    if (t.closest('.gtitle') || t.classList.contains('gtitle')) return 'title';
    if (t.closest('.legend')) return 'legend';
    if (t.closest('.annotation')) return 'annotation';
    const c = t.getAttribute('class') || '';
    if (/^[xy]\d*title$/.test(c)) return 'axistitle:' + c;
    const tick = t.closest('[class$="tick"]');
    if (tick) return 'tick:' + tick.getAttribute('class');
    if (c === 'cell-text') return 'cell';
    return 'other:' + c;
  };
  const texts = [];
  for (const t of root.querySelectorAll('text')) {
    if (!t.textContent.trim()) continue;
    const b = box(t); if (b.x1 - b.x0 <= 0) continue;
    const item = Object.assign({text: t.textContent, kind: kind(t)}, b);
    if (item.kind === 'cell') {
      const cell = t.closest('.column-cell').querySelector('.cell-rect');
      item.cell = box(cell);
      const view = t.closest('.table-control-view').querySelector('.scroll-background');
      item.view = view ? box(view) : null;
      item.header = t.closest('.column-block').id === 'header';
    }
    texts.push(item);
  }
  const leg = root.querySelector('.legend .bg');
  return {width: W.width, height: W.height, texts, legend: leg ? box(leg) : null};
}
"""


def measure(page: Any, selector: str = ".js-plotly-plot", index: int = 0) -> dict[str, Any]:
    """Text boxes of the ``index``-th plot matching ``selector`` on ``page``."""
    root = page.locator(selector).nth(index)
    return root.evaluate(MEASURE_JS)


def _overlap(a: dict[str, float], b: dict[str, float], slack: float = 1.0) -> bool:
    return (min(a["x1"], b["x1"]) - max(a["x0"], b["x0"]) > slack
            and min(a["y1"], b["y1"]) - max(a["y0"], b["y0"]) > slack)


def problems(m: dict[str, Any]) -> list[str]:
    """What is cut or overlapping in the measured figure ``m`` (empty when legible)."""
    out = []
    w, h = m["width"], m["height"]
    for t in m["texts"]:
        if t["x0"] < -1 or t["x1"] > w + 1 or t["y0"] < -1 or t["y1"] > h + 1:
            out.append(f"outside the figure: {t['text'][:50]!r} ({t['kind']})")
        if t["kind"] == "cell":
            c = t["cell"]
            if t["x0"] < c["x0"] or t["x1"] > c["x1"] - 1:
                out.append(f"wider than its cell: {t['text']!r}")
            v = t["view"]
            if v is not None and not t["header"] and c["y1"] > v["y1"] + 1:
                out.append(f"scrolled out of the table: {t['text']!r}")
    # overlaps between distinct pieces of text (ticks of one axis may touch each other)
    def group(t: dict[str, Any]) -> str:
        return t["kind"]

    labelled = [t for t in m["texts"] if t["kind"] != "cell" and not t["kind"].startswith("other")]
    boxes = list(labelled)
    if m["legend"] is not None:
        boxes.append(dict(m["legend"], text="(legend)", kind="legend-box"))
        boxes = [t for t in boxes if t["kind"] != "legend"]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            if group(a) == group(b) and a["kind"].startswith("tick"):
                continue
            if group(a) == group(b) == "title":
                continue  # lines of one title
            if _overlap(a, b):
                out.append(f"overlap: {a['text'][:40]!r} ({a['kind']}) and "
                           f"{b['text'][:40]!r} ({b['kind']})")
    return out
