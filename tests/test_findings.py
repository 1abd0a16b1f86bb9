"""The findings' shared rules (budget.runner.findings), each on a small study whose answer is
known analytically (in the style of tests/toys/toy_study.py), and the report's HTML twin."""

import json
import math
import re
import shutil
import subprocess

import numpy as np
import pytest

from budget.runner.findings import RULES, findings, findings_json, findings_lines, findings_markdown
from budget.runner.run import run_study
from budget.runner.study import ClassSpec, Study, TrialResult, Truth, trial_seed_sequence
from simcam.config_base import ValidationSettings


class _Scn:
    hash = "rules"
    name = "rules"

    validation = ValidationSettings(trials=400, max_trials=4000, batch_trials=100)
    source = "test"

    def to_toml(self):
        return ""

    def model_dump(self, mode="json", exclude_none=True):
        return {"name": "rules"}


class RulesStudy(Study):
    """Per trial: a truth mu_k ~ N(mu0, 10) and a few estimators of it (see each class).

    * ``offset``: per-trial truth mu_k; ``published`` is mu_k + 2 (biased by exactly 2, twice the
      default tolerance, 10 % of the truths' rms of about 10),
      ``improved`` mu_k + N(0, 1) with stated sigma 1 (unbiased, right sigma),
      ``zero`` returns 0 (a reference: it does not estimate);
    * ``tiny``: fixed truth 1 (exact); both variants return 1 + 1e-9 (numerical error below
      the class's floor 1e-6; ``published`` only, ``improved`` adds N(0, 0.1));
    * ``gauge``: axis ``a`` undetermined (the estimate is mu_k + N(0, 5), stated sigma 0.01),
      axis ``b`` = mu_k + N(0, 1) with sigma 1.
    """

    name = "rules"
    title = "rules study"
    seed_document = "none"
    variants = ("published", "improved", "zero")
    reference_variants = ("zero",)

    def __init__(self, mu0=0.0, floor=1e-6, unit="1"):
        self.mu0, self.floor, self.unit = mu0, floor, unit

    def default_text(self):
        return 'name = "rules"\n'

    def from_dict(self, data, *, source):
        return _Scn()

    def classes(self, scenario):
        return (ClassSpec("offset", "offset", self.unit, ("a",), "", per_trial_truth=True),
                ClassSpec("tiny", "tiny", self.unit, ("a",), "", numerical_floor=self.floor),
                ClassSpec("gauge", "gauge", self.unit, ("a", "b"), "", per_trial_truth=True, undetermined=("a",)))

    def trial(self, scenario, seed, k):
        rng = np.random.default_rng(trial_seed_sequence(seed, k))
        mu = rng.normal(self.mu0, 10.0)
        e = {("offset", "published", "a"): mu + 2.0, ("offset", "improved", "a"): mu + rng.normal(),
             ("offset", "zero", "a"): 0.0,
             ("tiny", "published", "a"): 1.0 + 1e-9, ("tiny", "improved", "a"): 1.0 + rng.normal(0, 0.1),
             ("gauge", "improved", "a"): mu + rng.normal(0, 5.0), ("gauge", "improved", "b"): mu + rng.normal()}
        t = {k_: mu for k_ in e if k_[0] in ("offset", "gauge")}
        s = {("offset", "improved", "a"): 1.0, ("gauge", "improved", "a"): 0.01, ("gauge", "improved", "b"): 1.0}
        return TrialResult(estimates=e, truths=t, sigmas=s)

    def truths(self, scenario, seed):
        return {("tiny", "a"): Truth(1.0, 0.0)}


def _run(study, trials=400):
    # seed fixed: every assertion below holds far beyond the sampling error of 400 trials
    return run_study(study, study.load_scenario(), trials=trials, seed=3, workers=1, prewarm=False)


def _by_key(res):
    return {(f["class"], f["variant"], f["axis"]): f for f in findings(res)}


@pytest.fixture(scope="module")
def res():
    return _run(RulesStudy())


def test_every_finding_names_a_known_rule_and_the_json_carries_them(res):
    j = res.to_json()
    assert j["findings"] and all(f["rule"] in RULES for f in j["findings"])
    json.dumps(j, allow_nan=True)
    assert len(j["findings"]) == len(res.keys())


def test_reference_variant_is_labelled_a_reference_and_never_recovers(res):
    f = _by_key(res)[("offset", "zero", "a")]
    assert f["rule"] == "reference" and not f["recovered"]
    assert "reference" in f["text"] and "recover" not in f["text"]
    s = findings_json(res)["variants"]["zero"]
    assert s["reference"] and s["recovered"] == []
    # its truth's mean (0) is near zero against the truths' spread (10): no percentage
    assert f["bias_percent"] is None and "%" not in f["text"]


def test_sub_floor_bias_is_exact_to_numerical_precision_not_significant(res):
    st = res.statistics(("tiny", "published", "a"))
    assert st["bias"] == pytest.approx(1e-9, rel=1e-6)
    assert st["bias_significant"] is False and st["exact_to_numerical_precision"]
    f = _by_key(res)[("tiny", "published", "a")]
    assert f["rule"] == "holds" and f["recovered"] and "exact to numerical precision" in f["text"]


def test_without_a_floor_the_same_bias_is_significant_but_significance_is_not_the_verdict():
    res = _run(RulesStudy(floor=0.0), trials=20)
    st = res.statistics(("tiny", "published", "a"))
    assert st["bias_significant"] is True  # spread 0: any bias is significant
    # ... but 1e-9 is far inside 10 % of the truth 1: the verdict holds
    assert _by_key(res)[("tiny", "published", "a")]["rule"] == "holds"


def test_bias_percent_only_where_the_truth_is_far_from_zero_against_its_spread():
    near = _run(RulesStudy(mu0=0.5), trials=200)     # mean truth 0.5, spread 10
    far = _run(RulesStudy(mu0=200.0), trials=200)    # mean truth 200, spread 10
    k = ("offset", "published", "a")
    assert math.isnan(near.statistics(k)["bias_percent"])
    assert not re.search(r"[+-]\d+\.\d % of the truth", _by_key(near)[k]["text"])
    assert _by_key(near)[k]["rule"] == "fails"  # 2 against 10 % of the truths' rms (about 10)
    assert _by_key(far)[k]["rule"] == "holds"   # 2 against 10 % of about 200
    # bias exactly 2 against the trials' mean truth
    p = far.statistics(k)["bias_percent"]
    assert p == pytest.approx(100 * 2.0 / far.statistics(k)["truth"], rel=1e-9)
    assert f"{p:+.1f} %" in _by_key(far)[k]["text"]


def test_undetermined_axis_is_not_determined_without_a_sigma(res):
    st = res.statistics(("gauge", "improved", "a"))
    assert st["determined"] is False and "coverage" not in st and st["bias_significant"] is False
    f = _by_key(res)[("gauge", "improved", "a")]
    assert f["rule"] == "gauge" and f["verdict"] is None and not f["recovered"] and "not determined" in f["text"]
    assert "sigma" not in f["text"].replace("no sigma", "")
    # the determined axis of the same class keeps its sigma and coverage
    assert "coverage" in res.statistics(("gauge", "improved", "b"))
    assert "gauge" in findings_json(res)["recommendation"] or "Not determined" in findings_json(res)["recommendation"]
    assert any("not determined" in line for line in findings_lines(res))


def test_unit_one_is_never_printed(res):
    text = "\n".join(findings_markdown(res)) + "\n".join(findings_lines(res))
    assert not re.search(r"\d 1\b(?! ?%)", text.replace("+- 1 ", "")), text
    assert "bias 2 +- " in text


def test_correct_variant_recovers_and_is_recommended(res):
    f = _by_key(res)[("offset", "improved", "a")]
    assert f["rule"] == "holds" and f["recovered"]
    assert _by_key(res)[("offset", "published", "a")]["rule"] == "fails"
    rec = findings_json(res)["recommendation"]
    assert rec.startswith("Use `improved` for offset")


def test_report_opens_with_findings_and_writes_html(res, tmp_path):
    from budget.runner.report import write_report

    md = write_report(res, tmp_path / "rep").read_text()
    assert md.index("## Findings") < md.index("## Table")
    page = (tmp_path / "rep" / "report.html").read_text()
    assert 'id="findings"' in page and "data:image/png;base64," in page
    assert "http://" not in page and "https://" not in page  # nothing fetched from a network


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        p = shutil.which(name)
        if p:
            return p
    return None


def test_report_html_renders_in_a_real_browser(res, tmp_path):
    """Headless Chromium (Debian's ``chromium`` package) loads report.html: every figure
    decoded (naturalWidth > 0) and the Findings section present; a screenshot is written."""
    browser = _chromium()
    if browser is None:
        pytest.skip("chromium not installed (Debian: apt-get install -y chromium): the browser test needs it")
    from budget.runner.html import write_html
    from budget.runner.report import write_report

    rep = tmp_path / "rep"
    write_report(res, rep)
    # a copy with a script that writes what the browser saw into the DOM
    page = (rep / "report.html").read_text().replace("</body>", """<script>
window.addEventListener('load', () => {
  const imgs = Array.from(document.images);
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
  const f = document.getElementById('findings');
  document.body.setAttribute('data-check', `images=${imgs.length} loaded=${ok} findings=${f ? f.innerText.length : 0}`);
});
</script></body>""")
    probe = rep / "probe.html"
    probe.write_text(page)
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
             "--user-data-dir=" + str(tmp_path / "profile")]
    dom = subprocess.run([browser, *flags, "--virtual-time-budget=5000", "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120)
    m = re.search(r'data-check="images=(\d+) loaded=(\d+) findings=(\d+)"', dom.stdout)
    assert m, dom.stderr[-2000:]
    n, ok, flen = map(int, m.groups())
    assert n >= 1 and ok == n, (n, ok)
    assert flen > 100
    shot = tmp_path / "report.png"
    subprocess.run([browser, *flags, f"--screenshot={shot}", "--window-size=1200,2400", (rep / "report.html").as_uri()],
                   capture_output=True, text=True, timeout=120)
    assert shot.stat().st_size > 10_000
    assert write_html(rep / "report.md").read_text() == (rep / "report.html").read_text().replace(
        "<title>rules study: Monte Carlo validation</title>", "<title>rules study: Monte Carlo validation</title>")


def test_linecam_gauge_combinations_are_orthogonal_to_the_plans_null_space():
    """The combinations the line camera reports in place of roll, pitch, dx0, dy0 are
    determined: orthogonal (in model units) to every null direction that
    budget.linecam.calibrate.separability finds for stars seen on a line at x' = 0 (an
    independent eigen-decomposition of the Jacobian); and the derivation from that null
    space gives the same combinations."""
    from budget.linecam.calibrate import separability
    from budget.linecam.model import NominalCamera, Observations, parameter_scale
    from budget.linecam.parameters import GAUGE_COMBINATIONS, determined_combinations, gauge_combination_vector
    from budget.linecam.study import STUDY
    from simcam.linecam.camera import camera_truth, sample_y_mm
    from simcam.linecam.scenario import default as load_default

    sc = load_default()
    cam = NominalCamera.from_model(sc.camera)
    truth = camera_truth(sc, np.zeros(10))
    rng = np.random.default_rng(0)
    s = rng.uniform(0, sc.camera.n_pixels - 1, 300)
    b = truth.body_direction(np.full(s.size, truth.x_line_mm),
                             sample_y_mm(s, n_pixels=truth.n_pixels, pitch_mm=truth.pitch_mm))
    obs = Observations(b=b, sample=s, pass_index=np.zeros(s.size, int), hip=np.arange(s.size))
    sep = separability(cam, obs)
    assert set(sep.inseparable) == {"roll", "pitch", "dx0", "dy0"}
    scale = parameter_scale(cam)  # null_space is in px at the line's end per parameter
    from simcam.linecam.scenario import PARAMETERS

    for _, ang, px, sign in GAUGE_COMBINATIONS:
        g = gauge_combination_vector(cam.f_px, ang, px, sign)
        for comb in sep.null_space:
            n = np.array([comb.get(p, 0.0) for p in PARAMETERS]) / scale  # model units
            # |g.n| against |g||n|: zero to the 0.05 cut of the reported coefficients
            assert abs(g @ n) <= 0.06 * np.linalg.norm(g) * np.linalg.norm(n)
    derived = {(a, p): sg for _, a, p, sg in determined_combinations(sep.null_space, cam.f_px)}
    for _, ang, px, sign in GAUGE_COMBINATIONS:
        assert derived[(ang, px)] == pytest.approx(sign, rel=0.06)
    spec = {c.name: c for c in STUDY.classes(sc)}
    assert spec["exterior"].undetermined == ("roll", "pitch")
    assert spec["principal_point"].undetermined == ("dx0", "dy0")


def test_starcam_cause_of_the_published_hsfe_follows_the_numbers():
    """Seed 000's likely cause ("measures temporal noise") is given only when the published
    HSFE's mean sits nearer the temporal-noise floor TE x sqrt(2/frames) than the truth."""
    from types import SimpleNamespace

    from budget.starcam.study import STUDY as STARCAM

    scn = SimpleNamespace(protocols=SimpleNamespace(hsfe=SimpleNamespace(frames=30, conditions=12, step_px=0.2)))
    # TE's truth as the run's statistics give it (the run's, or the mean of each trial's camera's)
    res = SimpleNamespace(scenario=scn, samples={("te", "published", "x"): [0.2]},
                          truths={}, statistics=lambda key: {"truth": 0.21})
    floor = 0.21 * (2 / 30) ** 0.5  # 0.0542
    at_floor = STARCAM.likely_cause(res, ("hsfe", "published", "x"), {"mean": 0.055, "truth": 0.043, "bias": 0.012})
    assert "measures temporal noise" in at_floor and f"{floor:.3g}" in at_floor
    # the noisy camera: the static error dominates, the mean (0.51) is far from the floor
    far = STARCAM.likely_cause(res, ("hsfe", "published", "x"), {"mean": 0.51, "truth": 1.06, "bias": -0.55})
    assert "measures temporal noise" not in far and "depends on which dominates" in far
    # the improved estimator's cause only for a low bias
    assert STARCAM.likely_cause(res, ("hsfe", "improved", "x"), {"mean": 0.03, "truth": 0.043, "bias": -0.013})
    assert STARCAM.likely_cause(res, ("hsfe", "improved", "x"), {"mean": 0.05, "truth": 0.043, "bias": 0.007}) is None


class StatedStudy(RulesStudy):
    """``spread``: a stated sigma (estimate) against the actual error (truth): ``published``
    states twice the actual |e|, ``improved`` states exactly it; role "stated". ``left``: what
    a compensation leaves (truth 0), role "residual"."""

    variants = ("published", "improved")
    reference_variants = ()

    def classes(self, scenario):
        return (ClassSpec("spread", "stated spread", "arcsec", ("a",), "", per_trial_truth=True, role="stated"),
                ClassSpec("left", "residual", "arcsec", ("a",), "", role="residual"))

    def trial(self, scenario, seed, k):
        rng = np.random.default_rng(trial_seed_sequence(seed, k))
        e = abs(rng.normal(1.0, 0.1))
        return TrialResult(estimates={("spread", "published", "a"): 2 * e, ("spread", "improved", "a"): e,
                                      ("left", "published", "a"): 0.5 + rng.normal(0, 0.1),
                                      ("left", "improved", "a"): rng.normal(0, 0.1)},
                           truths={("spread", "published", "a"): e, ("spread", "improved", "a"): e})

    def truths(self, scenario, seed):
        return {("left", "a"): Truth(0.0, 0.0)}


def test_stated_and_residual_roles_are_never_called_an_estimators_bias():
    res = _run(StatedStudy(), trials=200)
    f = _by_key(res)
    pub, imp = f[("spread", "published", "a")], f[("spread", "improved", "a")]
    # twice the actual (about 1) against 10 % of it: fails; exactly it: holds
    assert pub["rule"] == "fails" and "it states" in pub["text"] and not pub["recovered"]
    assert imp["rule"] == "holds" and "it states" in imp["text"] and imp["recovered"]
    left = f[("left", "published", "a")]
    assert "the residual, what the compensation leaves" in left["text"] and "bias" not in left["text"]
    # a truth of 0 has no 10 % to take: no verdict without a declared tolerance, said so
    for v in ("published", "improved"):
        g = f[("left", v, "a")]
        assert g["rule"] == "none" and g["verdict"] is None and not g["recovered"]
        assert "--tolerance CLASS=VALUE" in g["text"]
