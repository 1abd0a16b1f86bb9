"""The world of seed 004: a TDI line camera on a scanning spacecraft, imaging stars.

* :mod:`simcam.linecam.scenario` -- the strict scenario (embedded default ``data/default.toml``);
* :mod:`simcam.linecam.camera` -- interior and exterior errors, forward/inverse camera models;
* :mod:`simcam.linecam.attitude` -- two-body orbit, scan attitude, shifted passes;
* :mod:`simcam.linecam.signal` -- a star's electrons (spectra chain) and the patent's shortcut;
* :mod:`simcam.linecam.world` -- apparent places per pass (:mod:`simcam.sky`), crossing times,
  the TDI rendering (:mod:`simcam.linecam.kernels`) and the detector chain, attitude reports.

See ``docs/linecam.md``.
"""
