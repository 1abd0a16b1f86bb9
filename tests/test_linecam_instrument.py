"""The line camera's instrument per trial (validation.instrument_seed): the Gaia world's
proper-motion errors and, when pinned, the camera's errors; the retired world.gaia_sky_seed."""

from __future__ import annotations

import numpy as np
import pytest

from budget.linecam.study import STUDY
from budget.runner.study import instrument_seed_sequence
from simcam.infra.errors import ScenarioError
from simcam.linecam.world import gaia_pm_offsets, sky_strip, world_sky_strip

_STARS = {"region": "manual", "ra_deg": 280.0, "dec_deg": -5.0}


def _sc(**validation):
    return STUDY.from_dict({"stars": _STARS, "validation": validation}, source="t")


def _offsets(sc, seed, k):
    rng = np.random.default_rng(instrument_seed_sequence(sc.validation.instrument_seed, seed, k).spawn(2)[1])
    w = world_sky_strip(sc, ra_deg=280.0, dec_deg=-5.0, rng=rng)
    base = sky_strip(sc, ra_deg=280.0, dec_deg=-5.0, mag_limit=sc.stars.world_mag_limit, gaia=True)
    return w.directions - base.directions


def test_gaia_offsets_are_drawn_per_trial_or_pinned():
    free = _sc()
    a, b = _offsets(free, 0, 0), _offsets(free, 0, 1)
    assert np.max(np.abs(a)) > 0 and not np.array_equal(a, b)          # a new sky per trial
    np.testing.assert_array_equal(a, _offsets(free, 0, 0))             # reproducible
    pinned = _sc(instrument_seed=7)
    p = _offsets(pinned, 0, 0)
    np.testing.assert_array_equal(p, _offsets(pinned, 0, 5))           # every trial
    np.testing.assert_array_equal(p, _offsets(pinned, 3, 2))           # every run seed


def test_gaia_offsets_size_follows_the_formal_errors():
    """The offsets are dmu dt with dmu ~ N(0, (k sigma)^2): their rms over the strip's stars in
    one pass, against sqrt(mean((k sigma_pm dt)^2)) per component, within the sampling error of
    a mean square over M stars (relative sd sqrt(2 / M) of a chi-square; 5 of them)."""
    from astropy.time import Time

    from simcam.sky.catalogue import EPOCH_JYEAR
    from simcam.sky.gaia import GAIA_EPOCH_JYEAR, gaia_match
    from simcam.units import MAS_PER_RAD

    sc = _sc()
    k_sig = sc.world.effects.gaia_pm_error_sigmas
    base = sky_strip(sc, ra_deg=280.0, dec_deg=-5.0, mag_limit=sc.stars.world_mag_limit, gaia=True)
    w = gaia_pm_offsets(base, sc.stars.world_mag_limit, k_sig, np.random.default_rng(1))
    d = np.linalg.norm(w.directions[0] - base.directions[0], axis=1) * MAS_PER_RAD
    m = gaia_match(sc.stars.world_mag_limit)
    row = np.searchsorted(m.hip, base.cat.hip)
    t = Time(sc.orbit.epoch_utc, scale="utc").jyear
    dt = t - np.where(m.matched[row], GAIA_EPOCH_JYEAR, EPOCH_JYEAR)
    expect = np.mean((k_sig * dt) ** 2 * (m.pm_ra_err_mas_yr[row] ** 2 + m.pm_dec_err_mas_yr[row] ** 2))
    n = row.size
    assert n > 100
    assert np.mean(d**2) == pytest.approx(expect, rel=5 * np.sqrt(2.0 / n))


def test_pinned_instrument_pins_the_camera():
    pinned = _sc(instrument_seed=7)
    a, b = STUDY.trial(pinned, 0, 0), STUDY.trial(pinned, 1, 3)
    keys = [k for k in a.truths if k[0] in ("exterior", "principal_point", "focal", "distortion")]
    assert keys and all(a.truths[k] == b.truths[k] for k in keys)
    free = _sc()
    c, d = STUDY.trial(free, 0, 0), STUDY.trial(free, 0, 1)
    assert all(c.truths[k] != d.truths[k] for k in keys)


def test_gaia_sky_seed_is_refused_naming_its_replacement():
    with pytest.raises(ScenarioError) as e:
        STUDY.from_dict({"world": {"gaia_sky_seed": 2016}}, source="old.toml")
    msg = str(e.value)
    assert "\n" not in msg and "gaia_sky_seed is replaced by validation.instrument_seed" in msg
    assert msg.startswith("old.toml: world:")
