"""`budget inductosyn fit --plot`: the figure has a caption derived from the numbers it draws
(printed under the plot's path, as `budget plot` prints its figures), and eq 8's model curve
carries the fitted nuisance offset, so that it passes through the model at the points."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from budget.cli import main as budget_main

P = 360  # pole pairs


def _tables(tmp_path):
    """A 24-face long-period table (constant, 1st and 2nd mechanical harmonics) and a 23-face
    short-period one (an offset, 1st and 2nd electrical harmonics), with a small seeded noise."""
    rng = np.random.default_rng(3)
    a24 = 15.0 * np.arange(24)
    t = np.radians(a24)
    e24 = 4.0 + 30.0 * np.cos(t) - 12.0 * np.sin(t) + 5.0 * np.sin(2 * t) + rng.normal(0, 0.3, 24)
    a23 = 360.0 / 23 * np.arange(23)
    ph = np.radians(P * a23)
    e23 = -18.0 + 17.0 * np.cos(ph) - 64.0 * np.sin(ph) + 8.0 * np.sin(2 * ph) + rng.normal(0, 0.3, 23)
    paths = []
    for name, a, e in (("t24.csv", a24, e24), ("t23.csv", a23, e23)):
        p = tmp_path / name
        p.write_text("angle_deg,error_arcsec\n" + "".join(f"{float(x)!r},{float(y)!r}\n" for x, y in zip(a, e)))
        paths.append(p)
    return paths, (a23, e23)


def _run(monkeypatch, argv):
    seen = {}
    real = Figure.savefig

    def capture(fig, *a, **kw):
        seen["axes"] = fig.axes
        return real(fig, *a, **kw)

    monkeypatch.setattr(Figure, "savefig", capture)
    budget_main(argv)
    return seen["axes"]


def test_short_period_plot_caption_and_curve(tmp_path, monkeypatch, capsys):
    (_, t23), (a, e) = _tables(tmp_path)
    png = tmp_path / "fit.png"
    axes = _run(monkeypatch, ["inductosyn", "fit", str(t23), "--period", "short", "--plot", str(png)])
    out = capsys.readouterr().out
    assert png.stat().st_size > 0
    # the independent reference: least squares on [1, cos, sin, cos 2, sin 2] of the electrical phase
    ph = np.radians(P * a)
    X = np.column_stack([np.ones_like(ph), np.cos(ph), np.sin(ph), np.cos(2 * ph), np.sin(2 * ph)])
    c, *_ = np.linalg.lstsq(X, e, rcond=None)
    r = e - X @ c
    before, after = 3 * np.std(e, ddof=1), 3 * np.std(r, ddof=1)
    caption = out.split(f"plot: {png}\n", 1)[1].strip()
    assert f"on 23 points against the electrical phase: 3 sigma {before:.2f} arcsec before the fit, {after:.2f} after" in caption
    assert f"largest residual {r[np.argmax(np.abs(r))]:+.2f} arcsec" in caption
    assert f"fitted offset {c[0]:+.2f} arcsec" in caption and "not compensated" in caption
    # the model curve passes through the model at the points (the offset drawn with it): at each
    # point's phase the curve (721 samples over 360 deg, linear between them) agrees with the
    # fitted value to the curve's sampling, |e''| dx^2 / 8 <= (17 + 64 + 4 * 8) (0.5 deg in rad)^2 / 8
    left = axes[0]
    lines = {ln.get_label(): ln for ln in left.get_lines()}
    curve = [ln for lab, ln in lines.items() if lab.startswith("model (with offset")]
    assert len(curve) == 1
    gx, gy = curve[0].get_xdata(), curve[0].get_ydata()
    px, py = lines["model at the points"].get_xdata(), lines["model at the points"].get_ydata()
    tol = (17 + 64 + 4 * 8) * np.radians(0.5) ** 2 / 8
    assert np.max(np.abs(np.interp(px, gx, gy) - py)) <= tol + 1e-9


def test_sequence_plot_caption_has_every_fit(tmp_path, monkeypatch, capsys):
    (t24, t23), _ = _tables(tmp_path)
    png = tmp_path / "seq.png"
    axes = _run(monkeypatch, ["inductosyn", "fit", str(t24), str(t23), "--period", "sequence", "--plot", str(png)])
    out = capsys.readouterr().out
    caption = out.split(f"plot: {png}\n", 1)[1].strip()
    assert len(axes) == 4
    assert caption.startswith("eq 7 (5 coefficients) on 24 points against the angle")
    assert ". eq 8 (5 coefficients) on 23 points against the electrical phase" in caption
    # eq 7's constant is a term of the compensation, not a nuisance offset: no offset sentence for it
    assert caption.count("fitted offset") == 1


def test_joint_plot_says_why_it_has_no_curve(tmp_path, monkeypatch, capsys):
    (t24, t23), _ = _tables(tmp_path)
    png = tmp_path / "joint.png"
    _run(monkeypatch, ["inductosyn", "fit", str(t24), str(t23), "--period", "both", "--plot", str(png)])
    caption = capsys.readouterr().out.split(f"plot: {png}\n", 1)[1].strip()
    assert caption.startswith("joint (") and "on 47 points" in caption and "no model curve" in caption
