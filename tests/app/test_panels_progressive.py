"""The Panels tab on a grid whose exact semivariogram is too dear: a sampled
estimate first, with error bars, then the refined one; a newer map stops it."""

from __future__ import annotations

import numpy as np

from rough_viewer.app.features.panels import FIRST_BUDGET, REFINE_BUDGET, PanelsFeature
from rough_viewer.app.server import build_app
from tests.helpers import face_cloud


def _too_dear_for_exact(monkeypatch):
    """The cost model of a fine grid of a big scan: neither exact method fits any
    budget, so every semivariogram of the tab is a sample (in small chunks: many
    places to stop)."""
    import rough_viewer.grid.variogram as variogram
    import rough_viewer.grid.variogram_sample as sample

    monkeypatch.setattr(variogram, "FRAME_SECONDS", 1.0)
    monkeypatch.setattr(variogram, "PAIR_SECONDS", 1.0)
    monkeypatch.setattr(variogram, "PAIR_SECONDS_COMPILED", 1.0)
    monkeypatch.setattr(sample, "CHUNK", 1 << 13)


def _panels_records(app):
    return [r for r in app.worker.records if r.kind == "PanelsJob"]


def test_an_estimate_first_then_the_refined_one_with_error_bars(server, monkeypatch):
    import rough_viewer.app.features.panels as panels

    _too_dear_for_exact(monkeypatch)
    real = panels.semivariograms
    budgets: list[float] = []
    shown: list[object] = []

    def spy(ijk, maps, g, **kw):
        budgets.append(kw["time_budget"])
        shown.append(app.feature(PanelsFeature).variogram.figure)
        return real(ijk, maps, g, **kw)

    monkeypatch.setattr(panels, "semivariograms", spy)
    app = build_app(server, face_cloud(30_000, seed=4), prefetch=False)
    assert app.wait_idle(120)
    names = [n for n, _ in _panels_records(app)[-1].stages]
    # the quick panels first, the trend across grids, then the refinement
    assert names[:2] == ["distribution", "variogram estimate"]
    assert names.index("grid sizes") < names.index("variogram") == len(names) - 1
    assert budgets == [FIRST_BUDGET, REFINE_BUDGET]
    fig = app.feature(PanelsFeature).variogram.figure
    assert fig is not shown[1]  # the refined figure replaced the estimate
    assert "random sample" in fig.layout.title.text and "standard error" in fig.layout.title.text
    for trace in fig.data:
        se = np.asarray(trace.error_y.array, dtype=float)
        assert se.shape == np.asarray(trace.y).shape and np.all(se[np.isfinite(se)] > 0)
    assert "random sample" in shown[1].layout.title.text  # the estimate had been shown
    app.stop()


def test_a_newer_map_cancels_the_refinement_on_a_fine_grid(server, monkeypatch):
    import rough_viewer.app.features.panels as panels

    _too_dear_for_exact(monkeypatch)
    app = build_app(server, face_cloud(30_000, seed=5), prefetch=False)
    assert app.wait_idle(120)
    real = panels.semivariograms
    runs: list[tuple[float, list[tuple[int, int]]]] = []

    def spy(ijk, maps, g, *, progress=None, time_budget=None, **kw):
        calls: list[tuple[int, int]] = []
        runs.append((time_budget, calls))

        def watched(done: int, total: int) -> None:
            calls.append((done, total))
            if len(runs) == 2 and len(calls) == 3:  # a newer map arrives mid-refinement
                app.map.model.value = "OLS"
            assert progress is not None
            progress(done, total)  # the job's: raises once the job is cancelled

        return real(ijk, maps, g, progress=watched, time_budget=time_budget, **kw)

    monkeypatch.setattr(panels, "semivariograms", spy)
    before = len(_panels_records(app))
    finest = [o for o in app.map.grid.options if o != "free"][-2:]  # the two finest presets
    app.map.grid.value = finest[1] if app.map.grid.value != finest[1] else finest[0]
    assert app.wait_idle(120)
    records = _panels_records(app)[before:]
    assert [r.outcome for r in records] == ["cancelled", "done"]
    assert [n for n, _ in records[0].stages][:2] == ["distribution", "variogram estimate"]
    budget, refine = runs[1]
    assert budget == REFINE_BUDGET
    assert len(refine) == 3 and refine[-1][0] < refine[-1][1]  # stopped inside the sample
    # the newer map's panels ran in full: estimate and refinement, for the OLS map
    assert [b for b, _ in runs[2:]] == [FIRST_BUDGET, REFINE_BUDGET]
    assert all(c[-1][0] == c[-1][1] for _, c in runs[2:])
    assert app.session.shown.settings.model == "ols"
    assert [t.name for t in app.feature(PanelsFeature).variogram.figure.data][0] == "OLS"
    app.stop()
