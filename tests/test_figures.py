"""Figures that state their point: titles inside the figure, compared panels
on one colour scale, every class and axis of a sweep store plotted, and captions whose numbers
are the numbers drawn (read back from the figure's own artists, not from the code's inputs)."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

import budget.figures as figures


def _plt():
    return figures.plt()


TITLES_INSIDE: dict = {}


@pytest.fixture
def captured(monkeypatch):
    """Every figure passed to :func:`budget.figures.save`, with whether its titles lay inside
    it when it was written (checked at ``savefig``, before the figure is closed)."""
    figs = []
    orig = figures.save

    def spy(fig, path, caption, **kw):
        savefig = fig.savefig

        def checked_savefig(*a, **k):
            TITLES_INSIDE[id(fig)] = _title_inside(fig)
            return savefig(*a, **k)

        fig.savefig = checked_savefig
        out = orig(fig, path, caption, **kw)
        figs.append((fig, out))
        return out

    monkeypatch.setattr(figures, "save", spy)
    return figs


def _numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?", text)]


# --------------------------------------------------------------------------- titles
def _title_inside(fig) -> bool:
    """An independent check: every title's drawn extent within the figure's bbox."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    box = fig.bbox
    for ax in fig.axes:
        for t in (ax.title, ax._left_title, ax._right_title):
            if t.get_text():
                e = t.get_window_extent(r)
                if e.x0 < box.x0 - 0.5 or e.x1 > box.x1 + 0.5 or e.y1 > box.y1 + 0.5:
                    return False
    return True


def test_a_title_too_long_for_its_figure_is_seen_and_made_to_fit(tmp_path, captured):
    plt = _plt()
    fig, axes = plt.subplots(1, 3, figsize=(6, 2.5))
    axes[1].set_title("a title far longer than its narrow panel could ever hold on one line " * 2)
    fig.tight_layout()
    assert not _title_inside(fig) and figures.titles_outside(fig)
    out = figures.save(fig, tmp_path / "t.png", "caption")
    (f, _), = captured
    assert TITLES_INSIDE[id(f)] and out.exists() and out.caption == "caption"


def test_every_scanmirror_and_whiskbroom_figure_title_fits(tmp_path, captured):
    """Figures drawn from small synthetic inputs: each title lies inside its figure."""
    from budget.scanmirror.pipeline import GroundErrors
    from budget.scanmirror.plots import plot_deviation_timeline, plot_trial_ground_errors
    from budget.whiskbroom.plots import plot_dv_hist

    t = np.linspace(0, 600, 200)
    errs = {n: GroundErrors(np.sin(t / 50) * k, np.cos(t / 70) * k)
            for n, k in (("uncompensated", 0.4), ("improved", 0.01))}
    plot_trial_ground_errors(None, None, {"t_s": t, "errors": errs}, tmp_path / "g.png")
    plot_deviation_timeline(t, 1e-4 + 1e-7 * t, -2e-4 + 0 * t, {"published": (1.1e-4, -2.1e-4),
                                                                   "improved": (1.0e-4, -2.0e-4)},
                            300.0, tmp_path / "d.png")
    rng = np.random.default_rng(1)
    res = SimpleNamespace(residuals={lv: SimpleNamespace(dv_mm_s=rng.normal(0, s, 300))
                                     for lv, s in ((0.001, 0.2), (0.0003, 0.1))})
    plot_dv_hist(res, tmp_path / "dv.png")
    assert len(captured) == 3
    for fig, path in captured:
        assert TITLES_INSIDE[id(fig)], path


# --------------------------------------------------------------------------- colour scale
def test_scanmirror_ground_error_maps_share_one_colour_scale(tmp_path, captured):
    from budget.scanmirror.pipeline import GroundErrors
    from budget.scanmirror.plots import plot_ground_error_maps

    n = 50
    world = SimpleNamespace(latlon=lambda g0: (np.linspace(0.1, 0.3, 2 * n), np.linspace(1.5, 2.1, 2 * n)))
    setup = SimpleNamespace(g0=None, scan=np.repeat([1, 2], n))
    names = ("uncompensated", "without_estimate", "published", "improved")
    scale = {"uncompensated": 0.4, "without_estimate": 0.2, "published": 0.03, "improved": 0.005}
    out = {"errors": {s: {nm: (np.full(n, scale[nm]) * (1 + 0.1 * s), np.linspace(0, scale[nm], n))
                          for nm in names} for s in (1, 2)}}
    errors = {s: {nm: GroundErrors(*e) for nm, e in row.items()} for s, row in out["errors"].items()}
    fig_path = plot_ground_error_maps(world, setup, errors, tmp_path / "maps.png")
    (fig, _), = captured
    from matplotlib.collections import PathCollection

    panels = [ax for ax in fig.axes if any(isinstance(c, PathCollection) for c in ax.collections)]
    sc = [c for ax in panels for c in ax.collections if isinstance(c, PathCollection)]
    assert len(panels) == 8 and len(sc) == 8
    lims = {(c.norm.vmin, c.norm.vmax) for c in sc}
    assert len(lims) == 1  # one scale for every panel
    vmax = max(float(np.max(np.hypot(*out["errors"][s][nm]))) for s in (1, 2) for nm in names)
    assert next(iter(lims))[1] == pytest.approx(vmax, rel=1e-12)
    # one colour bar, not one per panel
    assert len(fig.axes) == len(panels) + 1
    # the caption's largest errors are the drawn ones (last scan), in deg, 3 significant digits
    for nm in names:
        want = float(np.max(np.hypot(*out["errors"][2][nm])))
        got = float(re.search(rf"{nm} ([0-9.e+-]+) deg", fig_path.caption).group(1))
        assert got == pytest.approx(want, rel=5e-3)


# --------------------------------------------------------------------------- captions = drawn
def test_linecam_residual_caption_gives_the_rms_of_the_points_drawn(tmp_path, captured):
    from budget.linecam.report import plot_residuals

    rng = np.random.default_rng(3)
    n = 120
    ex = {"sample": np.sort(rng.uniform(0, 6000, n)),
          "residual_before_px": np.r_[rng.normal(-13, 0.3, n), rng.normal(-19, 0.4, n)],
          "residual_after_px": {"published": rng.normal(0, 0.25, 2 * n), "improved": rng.normal(0, 0.2, 2 * n)}}
    path = plot_residuals(ex, tmp_path / "r.png")
    (fig, _), = captured
    drawn = {}
    for i, ax in enumerate(fig.axes):
        for line in ax.get_lines():
            y = np.asarray(line.get_ydata(), dtype=float)
            drawn[(line.get_label(), i)] = float(np.sqrt(np.mean(y ** 2)))
    cap = path.caption
    before = re.search(r"before calibration ([0-9.]+) / ([0-9.]+) px", cap)
    assert float(before.group(1)) == pytest.approx(drawn[("before (nominal camera)", 0)], abs=0.005)
    assert float(before.group(2)) == pytest.approx(drawn[("before (nominal camera)", 1)], abs=0.005)
    for v in ("published", "improved"):
        m = re.search(rf"{v} ([0-9.]+) / ([0-9.]+) px", cap)
        # printed with 3 decimals: equal within half a unit of the last digit
        assert float(m.group(1)) == pytest.approx(drawn[(f"after: {v}", 0)], abs=5e-4)
        assert float(m.group(2)) == pytest.approx(drawn[(f"after: {v}", 1)], abs=5e-4)


def test_scanmirror_trial_caption_gives_the_largest_error_drawn(tmp_path, captured):
    from budget.scanmirror.pipeline import GroundErrors
    from budget.scanmirror.plots import plot_trial_ground_errors

    t = np.linspace(0, 100, 300)
    errs = {"uncompensated": GroundErrors(0.3 * np.sin(t), 0.5 * np.cos(t / 3)),
            "published": GroundErrors(0.02 * np.sin(t), -0.04 + 0 * t)}
    path = plot_trial_ground_errors(None, None, {"t_s": t, "errors": errs}, tmp_path / "g.png")
    (fig, _), = captured
    drawn = {}
    for ax in fig.axes:
        for line in ax.get_lines():
            drawn[line.get_label()] = max(drawn.get(line.get_label(), 0.0), float(np.max(np.abs(line.get_ydata()))))
    for name, want in drawn.items():
        got = float(re.search(rf"{name} ([0-9.e+-]+) deg", path.caption).group(1))
        assert got == pytest.approx(want, rel=5e-3)  # 3 significant digits
    # smallest first
    assert path.caption.index("published") < path.caption.index("uncompensated")


def test_whiskbroom_mtf_caption_gives_the_crossing_of_the_curves_drawn(tmp_path, captured):
    """The most stages that keep the threshold, read from the drawn curves themselves."""
    from budget.whiskbroom.plots import plot_mtf_vs_stages

    res = SimpleNamespace(quantile=0.997, table=[
        {"mirror_rate_error_deg_s": 0.001, "eps_quantile": 0.0045, "eta_quantile": 0.002, "n_max_published": 71}])
    path = plot_mtf_vs_stages(res, tmp_path / "m.png", threshold=0.95, n_phase=4, max_stages=192)
    (fig, _), = captured
    solid, dashed = [ln for ln in fig.axes[0].get_lines() if len(ln.get_xdata()) > 2][:2]
    want = [int(np.asarray(ln.get_xdata())[np.asarray(ln.get_ydata()) >= 0.95].max()) for ln in (solid, dashed)]
    m = re.search(r"N <= (\d+) \(published\) vs (\d+) \(with clocking", path.caption)
    assert [int(m.group(1)), int(m.group(2))] == want


def test_overlaid_histograms_are_outlined_on_common_bins():
    plt = _plt()
    fig, ax = plt.subplots()
    edges = figures.overlaid_hist(ax, {"a": np.arange(10.0), "b": np.arange(10.0) + 0.5}, bins=5)
    outlines = [p for p in ax.patches if not p.get_fill()]
    assert len(outlines) == 2 and len({p.get_linestyle() for p in outlines}) == 2
    assert edges[0] == 0.0 and edges[-1] == 9.5
    plt.close(fig)


def test_figure_markdown_puts_each_caption_under_its_image(tmp_path):
    a = figures.Figure(tmp_path / "a.png").with_caption("A is 3 % below.")
    md = figures.figure_markdown([a])
    assert md.splitlines()[0] == "![a](a.png)" and "A is 3 % below." in md.splitlines()[2]
