"""The profile kernel (:func:`simcam.starcam.kernels.psf.stamp_profiles`)
with wavelengths of zero weight, against the same profiles without those wavelengths.

A filter passes some wavelengths of the scenario's grid and gives the others zero weight.
A term of zero weight is ``0 x (phase ramp)``, a signed zero, and a sum that adds signed
zeros to a running value that starts at +0 is unchanged bit for bit (round to nearest:
``x + (+-0) = x`` for ``x != 0`` and ``+0 + (-0) = +0``), so the profiles must equal, to the
bit, those computed on the wavelengths of non-zero weight alone (what the kernel does when
it skips them)."""

from __future__ import annotations

import numpy as np
import pytest

from simcam.starcam import psf_stamps as O


@pytest.mark.parametrize("kind", ["gaussian", "airy"])
def test_zero_weight_wavelengths_change_no_bit(kind):
    rng = np.random.default_rng(5)  # fixed seed: arbitrary widths, shifts and weights
    n, nl = 6, 25
    wl = np.linspace(400.0, 1000.0, nl)
    w = rng.random((n, nl))
    w[:, ::3] = 0.0         # a band every third wavelength blocked, for every star
    w[2, 1:9] = 0.0          # and one star's own blocked range
    keep = (w != 0.0).any(axis=0)
    kw = dict(stamp_px=24, psf_kind=kind, pinhole_radius_px=0.4, f_number=3.5, pixel_pitch_um=5.5)
    sig = (0.7 if kind == "gaussian" else 0.25) + 0.1 * rng.random(n)
    sx = 0.05 * rng.standard_normal((n, nl))
    sy = 0.05 * rng.standard_normal((n, nl))
    full = O.stamp_profiles(sigma_px=sig, wavelength_nm=wl, weights=w, shift_x_px=sx, shift_y_px=sy, **kw)
    part = O.stamp_profiles(sigma_px=sig, wavelength_nm=wl[keep], weights=w[:, keep], shift_x_px=sx[:, keep],
                            shift_y_px=sy[:, keep], **kw)
    assert full.spectra.shape == part.spectra.shape
    assert np.array_equal(full.spectra, part.spectra)
    assert np.array_equal(full.qmax, part.qmax)
