"""Traced products of a prescription: focus, image positions, spots and PSFs over field and wavelength.

For every field angle ``theta_f`` and wavelength ``lambda_l`` of the prescription's
``[analysis]`` grid, a bundle of ``rays_per_bundle`` parallel rays filling the entrance
pupil (:func:`simcam.starcam.lens.tracer.field_bundle`) is traced to image space and cut by the
image plane. The products are:

* **focus**: the image plane. ``best``: the plane minimising the mean, over every
  bundle, of the mean-square spot radius about the bundle's centroid. With straight rays
  after the last surface, the spot of a bundle at ``z`` is ``a + z s`` (``s`` the ray
  slopes), so the objective ``sum_b [var(a_b) + 2 z cov(a_b, s_b) + z^2 var(s_b)]`` is
  quadratic in ``z`` and its minimum is ``z* = -sum cov(a, s) / sum var(s)`` (exact, one
  pass; located with ``focus_rays_per_bundle`` rays per bundle, then all products are
  traced with the full bundles). ``paraxial``: the paraxial focus at the reference
  wavelength (ABCD, :mod:`simcam.starcam.lens.paraxial`); ``prescription``: the last thickness.
* **centroid** ``(x, y)`` of every spot on the image plane (mm): the image position. The
  centroid of the diffraction PSF equals that of the geometric spot (the mean wavefront
  tilt over a uniformly filled pupil; M. R. Teague, "Irradiance moments: their
  propagation and use for unique retrieval of phase", J. Opt. Soc. Am. 72, 1199, 1982),
  so it is what a star centroid measures. Against field it is the distortion, against
  wavelength the lateral colour.
* **chief ray** landing point (the ray through the centre of the entrance pupil).
* **spot size**: rms about the centroid per axis and rms radius (mm); vignetted fraction
  and losses per surface and reason.
* **PSF**: the spot turned into a pixel-integrated PSF stamp with diffraction: the
  geometric spot (rays binned on a grid ``1/q`` px fine) convolved with the Airy pattern
  of the entrance pupil at that wavelength and integrated over each pixel, computed in
  the Fourier domain as ``spot_spectrum x OTF_Airy(rho / rho_c) x sinc(f_x) sinc(f_y)``
  (Goodman, Introduction to Fourier Optics, Secs. 6.3-6.4: the incoherent OTF of a
  circular pupil ``(2/pi)(acos v - v sqrt(1 - v^2))``, cutoff ``rho_c = p / (lambda N)``).
  ``q`` is an even integer above ``2 rho_c``, so the band-limited image is sampled without
  aliasing and every ``q``-th sample is an exact pixel integral of the binned spot. The
  convolution of geometric spot and Airy pattern is the usual approximation of the PSF of
  an aberrated system (exact in the limits of small and of large aberrations); stamps are
  periodic (``psf_stamp_px`` wide) and centred on the centroid.

The sign convention is the lens's: a star at ``+theta`` (towards +x) images at negative
``x`` (the image is inverted). :mod:`simcam.starcam.lens.simulator` maps this onto the
simulator's focal-plane coordinates.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from dataclasses import dataclass, field, fields
from functools import lru_cache
from pathlib import Path

import numpy as np

import simcam
from simcam.infra.lifecycle import safe_filename
from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.paraxial import paraxial
from simcam.starcam.lens.prescription import PRODUCTS_VERSION, load_prescription
from simcam.starcam.lens.tracer import LOSS_REASONS, LensTracer, field_bundle
from simcam.starcam.psf_transfer import airy_otf

__all__ = [
    "SPOT_SAMPLES",
    "LensProducts",
    "best_focus_z",
    "cache_dir",
    "cache_path",
    "compute_products",
    "lens_products",
    "psf_stamp",
]

#: Rays kept per bundle for spot diagrams.
SPOT_SAMPLES = 1500


def cache_dir() -> Path:
    """Directory of the products cache: ``$SIMCAM_CACHE_DIR/lens``, else
    ``$XDG_CACHE_HOME/simcam/lens`` (``~/.cache/simcam/lens``)."""
    env = os.environ.get("SIMCAM_CACHE_DIR")
    if env:
        return Path(env) / "lens"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "simcam" / "lens"


def cache_path(prescription) -> Path:
    """Cache file of a prescription's products: ``cache_dir()/NAME-HASH.nc``, where NAME is
    the prescription's name made a safe file name (:func:`simcam.infra.lifecycle.safe_filename`):
    a name from an input file never leads out of the cache folder."""
    return cache_dir() / f"{safe_filename(prescription.name, default='lens')}-{prescription.hash}.nc"


# ----------------------------------------------------------------------------------------
# PSF from a spot


@lru_cache(maxsize=64)
def _transfer(L: int, q: int, cutoff: float) -> np.ndarray:
    """``OTF_Airy(rho / rho_c) sinc(f_x) sinc(f_y)`` on the DFT frequencies of an ``L q`` grid of step ``1/q`` px."""
    f = np.fft.fftfreq(L * q, d=1.0 / q)  # cycles/px
    fy, fx = np.meshgrid(f, f, indexing="ij")
    out = airy_otf(np.hypot(fx, fy), cutoff) * np.sinc(fx) * np.sinc(fy)
    out.setflags(write=False)
    return out


def psf_oversampling(cutoff_cyc_per_px: float) -> int:
    """Smallest even ``q >= 4`` with ``q / 2 > cutoff`` (fine grid free of aliasing)."""
    return max(4, 2 * (math.floor(cutoff_cyc_per_px) + 1))


def psf_stamp(*, x_px, y_px, wavelength_nm: float, f_number: float, pixel_pitch_um: float,
              stamp_px: int = 32, oversample: int | None = None) -> tuple[np.ndarray, float]:
    """Pixel-integrated PSF of a geometric spot with diffraction (see module docstring).

    Parameters
    ----------
    x_px, y_px : array_like (N,)
        Ray landing points relative to the stamp centre (the centre of pixel
        ``[stamp_px // 2, stamp_px // 2]``), px. Every ray carries weight ``1/N``.
    wavelength_nm, f_number, pixel_pitch_um : float
        For the Airy cutoff ``rho_c = p / (lambda N)`` in cycles/px.
    stamp_px : int
        Even stamp size (default 32).
    oversample : int, optional
        Fine-grid factor ``q`` (default :func:`psf_oversampling`).

    Returns
    -------
    stamp : ndarray (stamp_px, stamp_px)
        Fraction of the light in each pixel, ``stamp[row (y), col (x)]`` (sums to 1:
        the stamp is periodic).
    outside : float
        Fraction of the rays beyond the stamp (wrapped around).
    """
    L = int(stamp_px)
    if L < 2 or L % 2:
        raise LensError(f"stamp_px: must be an even integer >= 2, got {stamp_px}")
    x = np.asarray(x_px, dtype=np.float64).ravel()
    y = np.asarray(y_px, dtype=np.float64).ravel()
    if x.size == 0 or x.size != y.size:
        raise LensError("psf_stamp: needs the same number (> 0) of x and y ray positions")
    cutoff = pixel_pitch_um / (wavelength_nm * 1e-3 * f_number)
    q = psf_oversampling(cutoff) if oversample is None else int(oversample)
    if q < 1 or q / 2.0 <= cutoff:
        raise LensError(f"oversample: {q} too coarse for the Airy cutoff {cutoff:.3g} cycles/px")
    m = L * q
    kx = np.rint(x * q).astype(np.int64) + m // 2
    ky = np.rint(y * q).astype(np.int64) + m // 2
    outside = float(np.mean((kx < 0) | (kx >= m) | (ky < 0) | (ky >= m)))
    hist = np.bincount((ky % m) * m + (kx % m), minlength=m * m).reshape(m, m).astype(np.float64)
    hist /= x.size
    fine = np.fft.ifft2(np.fft.fft2(hist) * _transfer(L, q, cutoff)).real
    stamp = fine[::q, ::q] * float(q * q)  # every q-th fine sample is a pixel centre (mass / q^2 each)
    return stamp, outside


# ----------------------------------------------------------------------------------------
# products


@dataclass(frozen=True, eq=False)
class LensProducts:
    """Tables traced from a prescription (lengths in mm on the image plane, lens frame).

    Arrays are indexed ``[field, wavelength]``; see the module docstring for each quantity.
    """

    prescription_name: str
    prescription_hash: str
    variant: str
    field_deg: np.ndarray
    wavelength_nm: np.ndarray
    reference_wavelength_nm: float
    efl_mm: float
    bfd_mm: float
    f_number: float
    entrance_pupil_radius_mm: float
    entrance_pupil_z_mm: float
    paraxial_efl_mm: np.ndarray  # per wavelength
    paraxial_bfd_mm: np.ndarray  # per wavelength
    focus: str
    image_z_mm: float
    last_vertex_z_mm: float
    rays_per_bundle: int
    centroid_x_mm: np.ndarray
    centroid_y_mm: np.ndarray
    chief_x_mm: np.ndarray
    sigma_x_mm: np.ndarray
    sigma_y_mm: np.ndarray
    transmitted_fraction: np.ndarray
    losses: np.ndarray  # [field, wavelength, surface, reason]
    pixel_pitch_um: float
    psf: np.ndarray  # [field, wavelength, row, col]
    psf_outside_fraction: np.ndarray
    spot_dx_mm: np.ndarray  # [field, wavelength, sample] relative to the centroid (NaN: vignetted)
    spot_dy_mm: np.ndarray
    elapsed_s: float = 0.0
    from_cache: bool = field(default=False, compare=False)

    @property
    def back_focal_distance_mm(self) -> float:
        """Distance from the last vertex to the image plane of the products, mm."""
        return self.image_z_mm - self.last_vertex_z_mm

    @property
    def rms_radius_mm(self) -> np.ndarray:
        """rms spot radius about the centroid, mm."""
        return np.hypot(self.sigma_x_mm, self.sigma_y_mm)

    # ------------------------------------------------------------------ storage
    _SCALARS = ("prescription_name", "prescription_hash", "variant", "reference_wavelength_nm", "efl_mm",
                "bfd_mm", "f_number", "entrance_pupil_radius_mm", "entrance_pupil_z_mm", "focus",
                "image_z_mm", "last_vertex_z_mm", "rays_per_bundle", "pixel_pitch_um", "elapsed_s")

    def to_dataset(self):
        """The products as an :class:`xarray.Dataset` (dimensions field, wavelength, ...)."""
        import xarray as xr

        fw = ("field", "wavelength")
        ds = xr.Dataset(
            {
                "paraxial_efl_mm": (("wavelength",), self.paraxial_efl_mm),
                "paraxial_bfd_mm": (("wavelength",), self.paraxial_bfd_mm),
                "centroid_x_mm": (fw, self.centroid_x_mm),
                "centroid_y_mm": (fw, self.centroid_y_mm),
                "chief_x_mm": (fw, self.chief_x_mm),
                "sigma_x_mm": (fw, self.sigma_x_mm),
                "sigma_y_mm": (fw, self.sigma_y_mm),
                "transmitted_fraction": (fw, self.transmitted_fraction),
                "losses": (fw + ("surface", "reason"), self.losses.astype(np.int64)),
                "psf": (fw + ("row", "col"), self.psf),
                "psf_outside_fraction": (fw, self.psf_outside_fraction),
                "spot_dx_mm": (fw + ("sample",), self.spot_dx_mm),
                "spot_dy_mm": (fw + ("sample",), self.spot_dy_mm),
            },
            coords={"field_deg": (("field",), self.field_deg), "wavelength_nm": (("wavelength",), self.wavelength_nm)},
        )
        for k in self._SCALARS:
            v = getattr(self, k)
            ds.attrs[k] = v if not isinstance(v, (np.floating, np.integer)) else v.item()
        ds.attrs["products_version"] = PRODUCTS_VERSION
        ds.attrs["simcam_version"] = simcam.__version__
        return ds

    @classmethod
    def from_dataset(cls, ds) -> LensProducts:
        """Inverse of :meth:`to_dataset`."""
        kw = {k: ds.attrs[k] for k in cls._SCALARS}
        for k in ("reference_wavelength_nm", "efl_mm", "bfd_mm", "f_number", "entrance_pupil_radius_mm",
                  "entrance_pupil_z_mm", "image_z_mm", "last_vertex_z_mm", "pixel_pitch_um", "elapsed_s"):
            kw[k] = float(kw[k])
        kw["rays_per_bundle"] = int(kw["rays_per_bundle"])
        for k in ("prescription_name", "prescription_hash", "variant", "focus"):
            kw[k] = str(kw[k])
        kw["field_deg"] = np.asarray(ds["field_deg"].values, dtype=np.float64)
        kw["wavelength_nm"] = np.asarray(ds["wavelength_nm"].values, dtype=np.float64)
        for f in fields(cls):
            if f.name in ds.data_vars:
                kw[f.name] = np.asarray(ds[f.name].values)
        return cls(**kw)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the products to a NetCDF file (atomically: temporary file, then rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".nc", dir=path.parent)
        os.close(fd)
        try:
            self.to_dataset().to_netcdf(tmp, engine="scipy")
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> LensProducts:
        """Read products written by :meth:`save`."""
        import xarray as xr

        with xr.open_dataset(path, engine="scipy") as ds:
            ds.load()
            if int(ds.attrs.get("products_version", -1)) != PRODUCTS_VERSION:
                raise LensError(f"{path}: products of another format version")
            return cls.from_dataset(ds)


def _bundle_moments(res, z_ref: float):
    """Per-bundle sums for the best focus: positions ``a`` at ``z_ref`` and slopes ``s``."""
    a = res.alive
    if not a.any():
        return None
    sx = res.dx[a] / res.dz[a]
    sy = res.dy[a] / res.dz[a]
    ax = res.x_mm[a] + (z_ref - res.z_mm[a]) * sx
    ay = res.y_mm[a] + (z_ref - res.z_mm[a]) * sy
    cov = np.mean((ax - ax.mean()) * (sx - sx.mean())) + np.mean((ay - ay.mean()) * (sy - sy.mean()))
    var = sx.var() + sy.var()
    return cov, var


def best_focus_z(results, *, z_ref: float) -> float:
    """Plane ``z`` (mm) minimising the mean over bundles of the mean-square spot radius.

    ``z* = z_ref - sum cov(a, s) / sum var(s)`` (module docstring), with ``a`` the ray
    positions on the plane ``z_ref`` and ``s`` their slopes.
    """
    num = den = 0.0
    for res in results:
        m = _bundle_moments(res, z_ref)
        if m is not None:
            num += m[0]
            den += m[1]
    if den <= 0.0:
        raise LensError("best focus: no bundle reached the image space with any spread of slopes")
    return z_ref - num / den


def compute_products(prescription, *, variant: str | None = None, tracer: LensTracer | None = None,
                     progress=None) -> LensProducts:
    """Trace the products of ``prescription`` on its ``[analysis]`` grid (no cache).

    Parameters
    ----------
    prescription : Prescription or str
    variant : str, optional
        Mitsuba variant (see :mod:`simcam.starcam.lens.backend`).
    tracer : LensTracer, optional
        Reuse a tracer (its prescription must be ``prescription``).
    progress : callable, optional
        Called as ``progress(done, total)`` after every bundle.

    Raises
    ------
    LensError
        A bundle that loses every ray (the message names the field, wavelength and the
        surface where most rays were lost).
    """
    t_start = time.perf_counter()
    p = load_prescription(prescription)
    tr = tracer if tracer is not None else LensTracer(p, variant=variant)
    if tr.prescription is not p and tr.prescription.hash != p.hash:
        raise LensError("compute_products: the tracer was built for another prescription")
    an = p.analysis
    para = paraxial(p, wavelength_nm=an.reference_wavelength_nm)
    para_l = [paraxial(p, wavelength_nm=float(w)) for w in an.wavelength_nm]
    z_last = float(p.vertex_z_mm[-1])
    counter = _BundleCounter(progress, an.field_deg.size * an.wavelength_nm.size * (2 if an.focus == "best" else 1))
    z_img = _image_plane_z(p, tr, para, z_last=z_last, counter=counter)
    chief = _chief_ray_x(p, tr, para, z_img=z_img)
    grid = _field_products(p, tr, para, z_img=z_img, counter=counter)
    return LensProducts(
        prescription_name=p.name, prescription_hash=p.hash, variant=tr.variant,
        field_deg=an.field_deg, wavelength_nm=an.wavelength_nm, reference_wavelength_nm=an.reference_wavelength_nm,
        efl_mm=para.efl_mm, bfd_mm=para.bfd_mm, f_number=para.f_number,
        entrance_pupil_radius_mm=para.entrance_pupil_radius_mm, entrance_pupil_z_mm=para.entrance_pupil_z_mm,
        paraxial_efl_mm=np.array([q.efl_mm for q in para_l]), paraxial_bfd_mm=np.array([q.bfd_mm for q in para_l]),
        focus=an.focus, image_z_mm=float(z_img), last_vertex_z_mm=z_last, rays_per_bundle=an.rays_per_bundle,
        chief_x_mm=chief, pixel_pitch_um=an.pixel_pitch_um, **grid,
        elapsed_s=time.perf_counter() - t_start,
    )


class _BundleCounter:
    """The bundles traced so far, reported as ``progress(done, total)`` after each."""

    def __init__(self, progress, total: int) -> None:
        self.progress = progress
        self.total = total
        self.done = 0

    def tick(self) -> None:
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total)


def _check_bundle(p, res, f, w) -> None:
    """A :class:`LensError` naming the field, wavelength and the surface where most rays were
    lost when every ray of the bundle ``res`` is lost."""
    if not res.alive.any():
        worst = np.unravel_index(int(np.argmax(res.losses())), res.losses().shape)
        raise LensError(
            f"{p.name}: every ray of the bundle at field {f:g} deg, {w:g} nm is lost (most at "
            f"surfaces.{worst[0]}: {LOSS_REASONS[worst[1]]}; {res.describe_losses()})"
        )


def _image_plane_z(p, tr: LensTracer, para, *, z_last: float, counter: _BundleCounter) -> float:
    """The image plane ``z`` (mm) of the analysis's focus: ``best`` (one pass over every field
    and wavelength with the smaller bundles, :func:`best_focus_z`), ``paraxial`` or the
    prescription's last thickness."""
    an = p.analysis
    fields_deg, wls = an.field_deg, an.wavelength_nm
    nf, nl = fields_deg.size, wls.size
    z_par = z_last + para.bfd_mm
    if an.focus == "best":
        # one pass over every field and wavelength with the smaller bundles
        nfr = an.focus_rays_per_bundle
        rays = [field_bundle(p, field_deg=float(f), n_rays=nfr, para=para) for f in fields_deg]
        batch = [np.concatenate([np.tile(r[k], nl) for r in rays]) for k in range(6)]
        wl_index = np.tile(np.repeat(np.arange(nl, dtype=np.uint32), nfr), nf)
        res = tr._trace_indexed(batch, wls, wl_index, np.tile(np.repeat(wls, nfr), nf))
        first = []
        for fi, f in enumerate(fields_deg):
            for li, w in enumerate(wls):
                b = res.subset(slice((fi * nl + li) * nfr, (fi * nl + li + 1) * nfr))
                _check_bundle(p, b, f, w)
                first.append(b)
                counter.tick()
        return best_focus_z(first, z_ref=z_par)
    if an.focus == "paraxial":
        return z_par
    return z_last + p.image_distance_mm


def _chief_ray_x(p, tr: LensTracer, para, *, z_img: float) -> np.ndarray:
    """Where the chief rays (one per field and wavelength, through the entrance-pupil centre)
    land on the image plane: ``x`` (mm, (fields, wavelengths); NaN where lost)."""
    an = p.analysis
    fields_deg, wls = an.field_deg, an.wavelength_nm
    nf, nl = fields_deg.size, wls.size
    chief = np.zeros((nf, nl))
    th = np.radians(fields_deg)
    d0 = np.stack([-np.sin(th), np.zeros(nf), np.cos(th)])
    zs = min(para.entrance_pupil_z_mm, -abs(float(p.surfaces[0].shape.sag(p.surfaces[0].semi_diameter_mm**2))),
             0.0) - 1.0
    tt = (zs - para.entrance_pupil_z_mm) / d0[2]
    c0 = [np.tile(a, nl) for a in (tt * d0[0], tt * d0[1], para.entrance_pupil_z_mm + tt * d0[2], d0[0], d0[1], d0[2])]
    res = tr._trace_indexed(c0, wls, np.repeat(np.arange(nl, dtype=np.uint32), nf), np.repeat(wls, nf))
    t = (z_img - res.z_mm) / res.dz
    chief[:] = np.where(res.alive, res.x_mm + t * res.dx, np.nan).reshape(nl, nf).T
    return chief


def _field_products(p, tr: LensTracer, para, *, z_img: float, counter: _BundleCounter) -> dict:
    """The full bundles of every field and wavelength traced to the image plane: their
    centroids, spot rms, transmitted fraction, losses, PSF stamps and spot samples, as the
    :class:`LensProducts` fields of those names."""
    an = p.analysis
    fields_deg, wls = an.field_deg, an.wavelength_nm
    nf, nl = fields_deg.size, wls.size
    shape = (nf, nl)
    cx, cy = np.zeros(shape), np.zeros(shape)
    sx, sy, trans, outside = np.zeros(shape), np.zeros(shape), np.zeros(shape), np.zeros(shape)
    losses = np.zeros(shape + (len(p.surfaces), 3), dtype=np.int64)
    L = an.psf_stamp_px
    psf = np.zeros(shape + (L, L))
    spot_dx = np.full(shape + (SPOT_SAMPLES,), np.nan)
    spot_dy = np.full(shape + (SPOT_SAMPLES,), np.nan)
    n = an.rays_per_bundle
    stride = max(1, n // SPOT_SAMPLES)
    pitch_mm = an.pixel_pitch_um * 1e-3
    wl_rays = np.repeat(wls, n)
    wl_index = np.repeat(np.arange(nl, dtype=np.uint32), n)
    for fi, f in enumerate(fields_deg):
        rays = field_bundle(p, field_deg=float(f), n_rays=n, para=para)
        res = tr._trace_indexed([np.tile(a, nl) for a in rays], wls, wl_index, wl_rays)
        for li, w in enumerate(wls):
            b = res.subset(slice(li * n, (li + 1) * n))
            _check_bundle(p, b, f, w)
            x, y = b.at_plane(z_img)
            mx, my = x.mean(), y.mean()
            cx[fi, li], cy[fi, li] = mx, my
            sx[fi, li], sy[fi, li] = x.std(), y.std()
            trans[fi, li] = b.alive.mean()
            losses[fi, li] = b.losses()
            psf[fi, li], outside[fi, li] = psf_stamp(
                x_px=(x - mx) / pitch_mm, y_px=(y - my) / pitch_mm, wavelength_nm=float(w),
                f_number=para.f_number, pixel_pitch_um=an.pixel_pitch_um, stamp_px=L,
            )
            full_x = np.full(n, np.nan)
            full_y = np.full(n, np.nan)
            full_x[b.alive] = x - mx
            full_y[b.alive] = y - my
            xs, ys = full_x[::stride][:SPOT_SAMPLES], full_y[::stride][:SPOT_SAMPLES]
            spot_dx[fi, li, : xs.size] = xs
            spot_dy[fi, li, : ys.size] = ys
            counter.tick()
        del res
    return dict(centroid_x_mm=cx, centroid_y_mm=cy, sigma_x_mm=sx, sigma_y_mm=sy, transmitted_fraction=trans,
                losses=losses, psf=psf, psf_outside_fraction=outside, spot_dx_mm=spot_dx, spot_dy_mm=spot_dy)


_MEMO: dict[str, LensProducts] = {}


def lens_products(prescription, *, use_cache: bool = True, variant: str | None = None,
                  progress=None) -> LensProducts:
    """Products of ``prescription``, from memory, the disk cache or a new trace.

    The disk cache (:func:`cache_dir`) holds one NetCDF file per prescription hash
    (:attr:`Prescription.hash`: the prescription, its glasses' coefficients and the
    products format); a new trace is written there atomically.
    """
    p = load_prescription(prescription)
    key = p.hash
    if use_cache and key in _MEMO:
        return _MEMO[key]
    path = cache_path(p)
    if use_cache and path.is_file():
        try:
            prod = LensProducts.load(path)
            object.__setattr__(prod, "from_cache", True)
            _MEMO[key] = prod
            return prod
        except (OSError, ValueError, KeyError, TypeError, LensError):  # unreadable or stale: trace again
            pass
    prod = compute_products(p, variant=variant, progress=progress)
    if use_cache:
        try:
            prod.save(path)
        except OSError:  # a read-only cache directory is not an error
            pass
        _MEMO[key] = prod
    return prod
