"""estimates.png (budget.runner.report.plot_estimates): every variant of a panel on the same bin
edges, a sample whose every trial is the same drawn as a labelled vertical line (not a one-bin
spike), and a caption that says so from what is drawn."""

import numpy as np
import pytest

from budget.runner.run import run_study
from budget.runner.study import ClassSpec, Study, TrialResult, Truth, trial_seed_sequence
from simcam.config_base import ValidationSettings


class _Scn:
    hash = "estimates"
    name = "estimates"

    validation = ValidationSettings(trials=40, max_trials=400, batch_trials=40)
    source = "test"

    def to_toml(self):
        return ""

    def model_dump(self, mode="json", exclude_none=True):
        return {"name": "estimates"}


class SpreadStudy(Study):
    """Class ``level`` (fixed truth 1): ``published`` ~ N(1, 1), ``improved`` ~ N(1.2, 0.05) (two
    very different spreads: separately binned, their bins would differ 20-fold), ``exact``
    returns the truth in every trial. Class ``offset`` (per-trial truth mu_k): ``published``
    = mu_k + N(0, 1), ``improved`` = mu_k + 0.25 exactly (a constant error, up to the rounding
    of mu_k + 0.25 - mu_k)."""

    name = "estimates"
    title = "estimates figure study"
    seed_document = "none"
    variants = ("published", "improved", "exact")

    def default_text(self):
        return 'name = "estimates"\n'

    def from_dict(self, data, *, source):
        return _Scn()

    def classes(self, scenario):
        return (ClassSpec("level", "level", "mm", ("a",)),
                ClassSpec("offset", "offset", "1", ("a",), per_trial_truth=True))

    def trial(self, scenario, seed, k):
        rng = np.random.default_rng(trial_seed_sequence(seed, k))
        mu = rng.normal(0.0, 10.0)
        est = {("level", "published", "a"): 1.0 + rng.normal(0.0, 1.0),
               ("level", "improved", "a"): 1.2 + rng.normal(0.0, 0.05),
               ("level", "exact", "a"): 1.0,
               ("offset", "published", "a"): mu + rng.normal(0.0, 1.0),
               ("offset", "improved", "a"): mu + 0.25}
        truths = {("offset", "published", "a"): mu, ("offset", "improved", "a"): mu}
        return TrialResult(estimates=est, truths=truths)

    def truths(self, scenario, seed):
        return {("level", "a"): Truth(1.0)}


@pytest.fixture(scope="module")
def result():
    study = SpreadStudy()
    # seed fixed; what is asserted holds for any seed (the samples' shapes, not their values)
    return run_study(study, study.load_scenario(), trials=40, seed=5, workers=1, prewarm=False)


def _drawn(monkeypatch, result, tmp_path):
    """The figure plot_estimates draws (captured as it is saved) and its caption."""
    from matplotlib.figure import Figure

    from budget.runner.findings import findings_json
    from budget.runner.report import plot_estimates

    seen = {}
    real_savefig = Figure.savefig

    def capture(fig, *a, **kw):
        seen["panels"] = {ax.get_title(): ax for ax in fig.axes if ax.get_visible()}
        return real_savefig(fig, *a, **kw)

    monkeypatch.setattr(Figure, "savefig", capture)
    out = plot_estimates(result, tmp_path / "estimates.png", findings_json(result))
    assert (tmp_path / "estimates.png").is_file()
    return seen["panels"], getattr(out, "caption", "")


def _step_x(ax):
    """The x vertices of each drawn step histogram, by label."""
    out = {}
    for p in ax.patches:
        out[p.get_label()] = np.unique(np.round(p.get_xy()[:, 0], 12))
    return out


def test_variants_of_a_panel_share_the_bin_edges(monkeypatch, result, tmp_path):
    panels, _ = _drawn(monkeypatch, result, tmp_path)
    x = {v: result.samples[("level", v, "a")] for v in ("published", "improved")}
    # the edges every variant must share: 30 bins over both samples together
    allv = np.concatenate(list(x.values()))
    edges = np.linspace(allv.min(), allv.max(), 31)
    steps = _step_x(panels["level (a)"])
    assert set(steps) == {"published", "improved"}
    for label, xs in steps.items():
        # a step outline's vertices are its bin edges: the common ones
        assert xs.shape == edges.shape and np.allclose(xs, edges, rtol=0, atol=1e-9 * np.ptp(allv)), label


def test_a_constant_sample_is_a_labelled_line(monkeypatch, result, tmp_path):
    panels, caption = _drawn(monkeypatch, result, tmp_path)
    ax = panels["level (a)"]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    exact = [lab for lab in lines if lab.startswith("exact")]
    assert exact == ["exact: every trial 1"]
    assert np.allclose(lines[exact[0]].get_xdata(), 1.0)
    assert "exact" not in _step_x(ax)  # no histogram of it
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "exact: every trial 1" in legend
    # a constant error (per-trial truths): the line at 0.25, the rounding of mu + 0.25 - mu aside
    ax = panels["offset (a)"]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    assert "improved: every trial 0.25" in lines
    assert set(_step_x(ax)) == {"published"}
    # the caption says it from the numbers drawn
    assert "Every trial gives the same value" in caption
    assert "level (a) exact 1 mm" in caption and "offset (a) improved 0.25" in caption
    assert "the same 30 bins" in caption
