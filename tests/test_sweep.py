"""Sweep files: parsing, grid expansion, seeds, hashes and bad input (nothing is evaluated here).

The running of sweeps (workers, resume, sensitivity, plots, CLI) is in test_sweep_run.py.
"""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

from budget.sweeps.spec import expand_values, load_sweep, point_identity, point_seed
from simcam.infra.errors import ScenarioError
from tiny_camera import TINY




def _write(tmp_path, body: str, name: str = "sweep.toml") -> str:
    (tmp_path / "tiny.toml").write_text(TINY)
    p = tmp_path / name
    p.write_text(textwrap.dedent(body))
    return str(p)


def _err(tmp_path, body: str) -> str:
    path = _write(tmp_path, body)
    with pytest.raises(ScenarioError) as ei:
        load_sweep(path)
    msg = str(ei.value)
    assert path in msg, msg  # every message names the sweep file
    return msg


# --------------------------------------------------------------------------- values
def test_ranges_expand_to_the_documented_values():
    # float values are rounded to 12 significant digits: compare with that tolerance
    assert expand_values("k", {"start": 0.5, "stop": 1.5, "num": 5}, source="f") == pytest.approx([0.5, 0.75, 1.0, 1.25, 1.5], rel=1e-12)
    assert expand_values("k", {"start": 10, "stop": 50, "step": 20}, source="f") == [10, 30, 50]
    assert all(isinstance(v, int) for v in expand_values("k", {"start": 10, "stop": 50, "step": 20}, source="f"))
    # float steps are rounded to 12 significant digits and include the end point
    assert expand_values("k", {"start": 0.1, "stop": 0.5, "step": 0.1}, source="f") == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5], rel=1e-12)
    assert expand_values("k", {"start": 60, "stop": 10, "step": -25}, source="f") == [60, 35, 10]
    assert expand_values("k", {"start": 1, "stop": 100, "num": 3, "scale": "log"}, source="f") == pytest.approx([1.0, 10.0, 100.0], rel=1e-12)
    assert expand_values("k", ["a", "b"], source="f") == ["a", "b"]
    n = expand_values("k", {"start": 10, "stop": 40, "num": 4}, source="f")
    assert n == [10, 20, 30, 40] and all(isinstance(v, int) for v in n)
    assert expand_values("k", {"start": 10, "stop": 20, "num": 4}, source="f")[1] == pytest.approx(13.3333333333, rel=1e-12)


@pytest.mark.parametrize("spec, needle", [
    ([], "empty list"),
    ({"start": 0.0, "stop": 1.0, "num": 0}, "empty range"),
    ({"start": 5, "stop": 1, "step": 1}, "empty range"),
    ({"start": 0.0, "stop": 1.0}, "exactly one of num and step"),
    ({"start": 0.0, "stop": 1.0, "num": 3, "stride": 2}, "unknown range key"),
    ({"start": 0.0, "stop": 1.0, "step": 0}, "non-zero"),
    ([1.0, [2.0, 3.0]], "must be numbers"),
    ([1.0, "a"], "mix"),
    ([1.0, 2.0, 1.0], "appears twice"),
    ("1, 2", "expected a list"),
])
def test_bad_values_are_named(spec, needle):
    with pytest.raises(ScenarioError, match=needle) as ei:
        expand_values("camera.exposure_s", spec, source="my.toml")
    assert str(ei.value).startswith("my.toml: parameters.camera.exposure_s: ")


# --------------------------------------------------------------------------- grids
def test_product_and_zip_grids_and_dimensions(tmp_path):
    sw = load_sweep(_write(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        evaluate = "truth"
        [parameters]
        "lab.source.match_v_mag" = [6.0, 7.0, 8.0]
        "optics.psf.sigma0_px" = {start = 0.8, stop = 1.2, num = 2}
    """))
    assert sw.dims == ("lab.source.match_v_mag", "optics.psf.sigma0_px") and sw.shape == (3, 2)
    assert [p.values for p in sw.points[:3]] == [
        {"lab.source.match_v_mag": 6.0, "optics.psf.sigma0_px": 0.8},
        {"lab.source.match_v_mag": 6.0, "optics.psf.sigma0_px": 1.2},
        {"lab.source.match_v_mag": 7.0, "optics.psf.sigma0_px": 0.8}]
    p = sw.points[5]
    assert sw.grid_index(5) == (2, 1)
    assert p.scenario.lab.source.match_v_mag == 8.0 and p.scenario.optics.psf.sigma0_px == 1.2
    # the rest of the scenario is the base's
    assert p.scenario.detector.chip_cols == 256

    z = load_sweep(_write(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        mode = "zip"
        [parameters]
        "protocols.te.frames" = [5, 10, 20]
        "protocols.hsfe.frames" = {start = 5, stop = 15, num = 3}
    """, "zip.toml"), check=False)
    assert z.dims == ("point",) and z.shape == (3,)
    assert [(q.scenario.protocols.te.frames) for q in z.points] == [5, 10, 20]
    assert [(q.scenario.protocols.hsfe.frames) for q in z.points] == [5, 10, 15]


def test_zip_needs_equal_lengths(tmp_path):
    msg = _err(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        mode = "zip"
        [parameters]
        "protocols.te.frames" = [5, 10, 20]
        "protocols.hsfe.frames" = [5, 10]
    """)
    assert "one length" in msg and "protocols.te.frames: 3" in msg


def test_index_and_wildcard_keys_reach_list_elements(tmp_path):
    sw = load_sweep(_write(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        evaluate = "truth"
        [fixed]
        "lab.target_center_px.1" = 3.0
        [parameters]
        "detector.chips.*.read_noise_e" = [2.0, 5.0]
    """))
    for p, rn in zip(sw.points, (2.0, 5.0)):
        assert [c.read_noise_e for c in p.scenario.detector.chips] == [rn, rn]
        # the other fields of each chip keep their (default) values
        assert [c.gain_e_per_dn for c in p.scenario.detector.chips] == [1.0, 1.05]
        assert p.scenario.lab.target_center_px == (-133.0, 3.0)


# --------------------------------------------------------------------------- bad input
def test_unknown_dotted_key_is_named_with_the_known_keys(tmp_path):
    msg = _err(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        [parameters]
        "detector.read_noise" = [1.0, 2.0]
    """)
    assert "'detector.read_noise'" in msg and "unknown key 'read_noise'" in msg
    assert "prnu_rms" in msg  # lists what exists there


def test_unknown_setting_of_the_sweep_file_is_named(tmp_path):
    msg = _err(tmp_path, """
        kind = "starcam"
        seed = 1
        trails = 20
        [parameters]
        "camera.exposure_s" = [0.1]
    """)
    assert "trails: unknown key" in msg


def test_value_the_scenario_rejects_names_point_key_and_reason(tmp_path):
    msg = _err(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        [parameters]
        "detector.prnu_rms" = [0.01, -0.1]
    """)
    assert "point 1 (detector.prnu_rms = -0.1)" in msg
    assert "detector.prnu_rms: Input should be greater than or equal to 0" in msg


def test_int_field_given_a_float_is_rejected(tmp_path):
    msg = _err(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        [parameters]
        "protocols.te.frames" = {start = 10, stop = 20, num = 4}
    """)
    assert "point 0 (protocols.te.frames = 10.0)" in msg and "valid integer" in msg


def test_star_off_the_detector_is_rejected_before_any_work(tmp_path):
    msg = _err(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        [parameters]
        "lab.target_center_px.0" = [-133.0, -600.0]
    """)
    assert "point 1" in msg and "off the detector" in msg and "protocol te" in msg


def test_polygon_that_cannot_separate_the_harmonics_is_rejected(tmp_path):
    # 24 faces divide the 360 pole pairs: the electrical harmonics alias onto a constant
    msg = _err(tmp_path, """
        kind = "inductosyn"
        seed = 1
        trials = 10
        [parameters]
        "calibration.short_polygon.faces" = [23, 24]
    """)
    assert "point 1 (calibration.short_polygon.faces = 24)" in msg and "cannot separate" in msg


K = 'kind = "starcam"\n'


@pytest.mark.parametrize("body, needle", [
    (K + 'seed = 1\nevaluate = "truth"\ntrials = 5\n[parameters]\n"camera.exposure_s" = [0.1]', "validate' only"),
    (K + 'seed = 1\ntrials = 5\ntolerance = 0.1\n[parameters]\n"camera.exposure_s" = [0.1]', "give one of them"),
    # no default study, and no former names: one line saying what to write
    ('seed = 1\n[parameters]\n"camera.exposure_s" = [0.1]', "kind: required, the registered study the sweep runs"),
    ('seed = 1\nkind = "camera"\n[parameters]\n"camera.exposure_s" = [0.1]',
     "kind = 'camera' is a former name: write kind = 'starcam'"),
    ('seed = 1\nkind = "nosuchstudy"\n[parameters]\n"camera.exposure_s" = [0.1]',
     "kind: 'nosuchstudy' is not a registered study (starcam, inductosyn"),
    (K + 'seed = 1\ntolerance_3sigma_arcsec = 0.1\n[parameters]\n"camera.exposure_s" = [0.1]',
     "tolerance_3sigma_arcsec: no longer a sweep setting; write tolerance"),
    (('seed = 1\nkind = "inductosyn"\nevaluate = "truth"\n[parameters]\n'
      '"calibration.short_polygon.faces" = [23]'), "not available for inductosyn"),
    (('seed = 1\nkind = "inductosyn"\ndense_step_deg = 0.01\n[parameters]\n'
      '"calibration.short_polygon.faces" = [23]'),
     'dense_step_deg: no longer a sweep setting; write [fixed] "validation.dense_step_deg"'),
    (K + 'seed = 1', "nothing to do"),
    (K + 'seed = 1\n[fixed]\n"camera.exposure" = 0.1\n[parameters]\n"camera.exposure_s" = [0.1]',
     "fixed: 'camera.exposure': unknown key 'exposure' at camera"),
    (K + 'seed = 1\n[fixed]\n"detector.n_chips" = 3\n[parameters]\n"camera.exposure_s" = [0.1]',
     "chips lists 2 chip(s) but n_chips = 3"),
    (K + '[parameters]\n"camera.exposure_s" = [0.1]', "seed: Field required"),
    (K + 'seed = 1\nbase = "missing.toml"\n[parameters]\n"camera.exposure_s" = [0.1]', "scenario file not found"),
])
def test_bad_settings(tmp_path, body, needle):
    assert needle in _err(tmp_path, body)


def test_sensitivity_settings_and_samples_are_checked(tmp_path):
    head = K + 'base = "tiny.toml"\nseed = 1\n[sensitivity]\n'
    assert "power of 2" in _err(tmp_path, head + 'samples = 6\n[sensitivity.parameters]\n'
                                '"detector.prnu_rms" = {dist = "uniform", low = 0.0, high = 0.02}\n')
    assert "uniform needs low, high (missing high)" in _err(
        tmp_path, head + 'samples = 4\n[sensitivity.parameters]\n"detector.prnu_rms" = {dist = "uniform", low = 0.0}\n')
    assert "needs evaluate = 'validate'" in _err(
        tmp_path, head + 'samples = 4\noutput = "improved"\n[sensitivity.parameters]\n'
        '"detector.prnu_rms" = {dist = "uniform", low = 0.0, high = 0.02}\n')
    # a normal distribution reaches negative PRNU: the sample the scenario rejects is named
    msg = _err(tmp_path, head + 'samples = 8\n[sensitivity.parameters]\n'
               '"detector.prnu_rms" = {dist = "normal", mean = 0.001, sd = 0.01}\n')
    assert "sensitivity sample" in msg and "detector.prnu_rms: Input should be greater than or equal to 0" in msg
    assert "unknown key 'prnu'" in _err(tmp_path, head + 'samples = 4\n[sensitivity.parameters]\n'
                                         '"detector.prnu" = {dist = "uniform", low = 0.0, high = 0.02}\n')


# --------------------------------------------------------------------------- seeds, hash
def test_point_seed_depends_only_on_sweep_seed_and_point_values(tmp_path):
    a = load_sweep(_write(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 7
        evaluate = "truth"
        [parameters]
        "lab.source.match_v_mag" = [6.0, 7.0]
        "optics.psf.sigma0_px" = [0.8, 1.2]
    """, "a.toml"))
    # another grid, other order of keys and points, 7 written as an integer: same point, same seed
    b = load_sweep(_write(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 7
        evaluate = "truth"
        [parameters]
        "optics.psf.sigma0_px" = [1.2, 1.0]
        "lab.source.match_v_mag" = [8.0, 7]
    """, "b.toml"))
    sa = {point_identity(p.values): p.seed for p in a.points}
    sb = {point_identity(p.values): p.seed for p in b.points}
    common = set(sa) & set(sb)
    assert len(common) == 1
    k = common.pop()
    assert sa[k] == sb[k]
    assert len(set(sa.values())) == len(sa)  # distinct points, distinct seeds
    v = {"optics.psf.sigma0_px": 1.2, "lab.source.match_v_mag": 7.0}
    assert point_seed(7, v) == sa[k] and point_seed(8, v) != sa[k]
    assert 0 <= sa[k] < 2**63


def test_hash_ignores_layout_but_not_content(tmp_path):
    body = """
        base = "tiny.toml"
        kind = "starcam"
        seed = 1
        evaluate = "truth"
        [parameters]
        "lab.source.match_v_mag" = [6.0, 7.0]
    """
    h1 = load_sweep(_write(tmp_path, body, "h1.toml")).hash
    h2 = load_sweep(_write(tmp_path, "# a comment\n" + body.replace("= [6.0, 7.0]", "=   [ 6.0,7.0 ]"),
                           "h2.toml")).hash
    h3 = load_sweep(_write(tmp_path, body.replace("7.0]", "7.5]"), "h3.toml")).hash
    assert h1 == h2 != h3
    # the base scenario's content is part of the hash
    (tmp_path / "tiny.toml").write_text(TINY.replace("frames = 10", "frames = 12"))
    from budget.sweeps.spec import load_sweep as again

    h4 = again(str(tmp_path / "h1.toml")).hash
    assert h4 != h1


def test_sobol_samples_follow_their_distributions(tmp_path):
    """Saltelli samples of U(0.6, 1.2) and an integer U(5, 30): in range, integers rounded,
    and the sample mean within 4 standard errors of the distribution's mean (N (D+2) draws
    of a (scrambled, so unbiased) Sobol sequence: the plain-MC standard error bounds it)."""
    sw = load_sweep(_write(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 2
        [sensitivity]
        samples = 16
        [sensitivity.parameters]
        "optics.psf.sigma0_px" = {dist = "uniform", low = 0.6, high = 1.2}
        "protocols.te.frames" = {dist = "uniform", low = 5, high = 30, integer = true}
    """), check=False)
    x = sw.samples
    assert x.shape == (16 * 4, 2)
    assert np.all((x[:, 0] >= 0.6) & (x[:, 0] <= 1.2))
    assert np.all(x[:, 1] == np.rint(x[:, 1]))
    se = (0.6 / np.sqrt(12)) / np.sqrt(len(x))
    assert abs(x[:, 0].mean() - 0.9) < 4 * se
    frames = [p.scenario.protocols.te.frames for p in sw.sample_points]
    assert all(isinstance(f, int) and 5 <= f <= 30 for f in frames)
    # every sample shares one seed (common random numbers)
    assert len({p.seed for p in sw.sample_points}) == 1


def test_identity_is_canonical_json():
    assert json.loads(point_identity({"b": 2, "a": 1.5, "c": "x"})) == [["a", "1.5"], ["b", "2.0"], ["c", "x"]]
