"""Sequential real-ray trace of a prescription: Mitsuba 3 intersections, our refraction.

Every surface is a Mitsuba shape in a scene of its own (the trace is sequential): a
``sphere`` of the vertex radius for a curved surface (conic and aspheric surfaces too:
their base sphere), a ``disk`` slightly larger than the clear aperture for a plane.
For each surface in turn:

1. **Mitsuba intersects** the ray bundle with the surface's shape
   (``Scene.ray_intersect_preliminary``, vectorised in the ``llvm_ad_rgb`` variant, one
   ray per call in ``scalar_rgb``): a miss vignettes the ray. A sphere is a whole
   sphere, so a hit on the far hemisphere (possible for a concave surface, ``R < 0``,
   seen from outside its sphere) is re-queried from that point to reach the vertex-side
   cap.
2. **The hit is refined in double precision** on the exact surface (Mitsuba works in
   single precision and knows no conic or aspheric terms): for a sphere or plane, the
   root of its quadratic nearest Mitsuba's distance (Mitsuba picks the sheet, the closed
   form gives the digits); for a conic or asphere, Newton's method on
   ``f(t) = z(t) - z_v - sag(x(t)^2 + y(t)^2)`` started at Mitsuba's distance (the
   iterative intersection of G. H. Spencer and M. V. R. K. Murty, "General ray-tracing
   procedure", J. Opt. Soc. Am. 52, 672-678, 1962), with the sag of
   :mod:`simcam.starcam.lens.surface`. A ray landing outside the semi-diameter is vignetted.
3. **Refraction** by Snell's law in vector form (e.g. A. S. Glassner, An Introduction to
   Ray Tracing, 1989, Sec. 5.3; Spencer & Murty eq. 37): with unit direction ``d``, unit
   normal ``N`` oriented along the propagation (``cos_i = N.d > 0``) and
   ``mu = n / n'`` (Sellmeier indices at the bundle's wavelength, computed here: Mitsuba's
   ``dielectric`` BSDF has one index and no dispersion)::

       k = 1 - mu^2 (1 - cos_i^2);    d' = mu d + (sqrt(k) - mu cos_i) N,

   and ``k < 0`` is total internal reflection: the ray is vignetted and counted.

Lost rays are counted by surface and reason (:data:`LOSS_REASONS`). In the vectorised
variant the whole bundle stays in Dr.Jit arrays (float64) between surfaces; per-bundle
scalars (indices) are opaque, so the compiled kernels are reused for every wavelength.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from simcam.starcam.lens.backend import Backend, get_backend, in_variant
from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.paraxial import ParaxialData, paraxial
from simcam.starcam.lens.prescription import Prescription, load_prescription
from simcam.starcam.lens.surface import NUMPY, SurfaceShape

__all__ = ["LOSS_REASONS", "LensTracer", "TraceResult", "field_bundle", "symmetric_pupil", "vogel_pupil"]

#: Why a ray is lost at a surface: code ``1 + 3 j + reason`` in :attr:`TraceResult.lost_code`.
LOSS_REASONS = ("miss", "aperture", "tir")

#: Mitsuba's query ray starts this far (mm) behind the current point, so that a surface
#: touching the previous one (zero gap at the vertex) is still found at t >= 0.
_BACKOFF_MM = 0.01
#: Disk shapes of plane surfaces are this much larger than the clear aperture (a plane,
#: for every ray of a sequential trace): the exact aperture test is done on the refined hit.
_DISK_MARGIN = 1000.0
#: Newton residual (mm) above which a refined hit is declared a miss.
_CONVERGED_MM = 1e-9


def _newton_steps(shape: SurfaceShape) -> int:
    if shape.is_flat:
        return 2
    if shape.is_sphere:
        return 3
    return 8


@dataclass(frozen=True, eq=False)
class TraceResult:
    """Rays after the last surface (image space), and what was lost where.

    Attributes
    ----------
    x_mm, y_mm, z_mm : ndarray (N,)
        Position on the last surface (lost rays: where they were lost).
    dx, dy, dz : ndarray (N,)
        Unit direction in image space.
    alive : ndarray of bool (N,)
    lost_code : ndarray of uint32 (N,)
        0 for a ray that reached image space, else ``1 + 3 j + r``: lost at surface ``j``
        (0-based) for reason ``LOSS_REASONS[r]``.
    wavelength_nm : float or ndarray (N,)
    n_surfaces : int
    path_mm : ndarray (n_surfaces, 3, N) or None
        With ``record_path=True``: the point of every ray on every surface (the last
        valid point for a lost ray).
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    z_mm: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    dz: np.ndarray
    alive: np.ndarray
    lost_code: np.ndarray
    wavelength_nm: float
    n_surfaces: int
    path_mm: np.ndarray | None = None

    @property
    def n_rays(self) -> int:
        """Rays launched."""
        return int(self.alive.size)

    def losses(self) -> np.ndarray:
        """Rays lost per surface and reason, shape ``(n_surfaces, 3)`` (columns :data:`LOSS_REASONS`)."""
        codes = self.lost_code[self.lost_code > 0].astype(np.int64) - 1
        counts = np.bincount(codes, minlength=3 * self.n_surfaces)[: 3 * self.n_surfaces]
        return counts.reshape(self.n_surfaces, 3)

    def subset(self, sl) -> TraceResult:
        """The rays ``sl`` (a slice or index array) of this result, e.g. one bundle of a batch."""
        wl = self.wavelength_nm
        return TraceResult(x_mm=self.x_mm[sl], y_mm=self.y_mm[sl], z_mm=self.z_mm[sl], dx=self.dx[sl],
                           dy=self.dy[sl], dz=self.dz[sl], alive=self.alive[sl], lost_code=self.lost_code[sl],
                           wavelength_nm=wl[sl] if isinstance(wl, np.ndarray) else wl, n_surfaces=self.n_surfaces,
                           path_mm=None if self.path_mm is None else self.path_mm[:, :, sl])

    def describe_losses(self) -> str:
        """One line per surface and reason with losses, e.g. ``surface 3: 120 aperture``."""
        lines = []
        for j, row in enumerate(self.losses()):
            parts = [f"{int(c)} {r}" for c, r in zip(row, LOSS_REASONS) if c]
            if parts:
                lines.append(f"surface {j}: " + ", ".join(parts))
        return "; ".join(lines) if lines else "none"

    def at_plane(self, z_mm: float) -> tuple[np.ndarray, np.ndarray]:
        """``(x, y)`` in mm where the surviving rays cross the plane ``z = z_mm`` (straight lines in image space)."""
        a = self.alive
        t = (z_mm - self.z_mm[a]) / self.dz[a]
        return self.x_mm[a] + t * self.dx[a], self.y_mm[a] + t * self.dy[a]


def vogel_pupil(n_rays: int) -> tuple[np.ndarray, np.ndarray]:
    """Points of the unit disc with uniform area density: Vogel's spiral.

    ``r_i = sqrt((i + 1/2) / n)``, ``phi_i = i pi (3 - sqrt 5)`` (the golden angle; H. Vogel,
    "A better way to construct the sunflower head", Math. Biosci. 44, 179-189, 1979).
    Every point stands for the same pupil area ``pi / n``.
    """
    if n_rays < 1:
        raise LensError(f"n_rays: must be >= 1, got {n_rays}")
    i = np.arange(n_rays, dtype=np.float64)
    r = np.sqrt((i + 0.5) / n_rays)
    phi = i * (math.pi * (3.0 - math.sqrt(5.0)))
    return r * np.cos(phi), r * np.sin(phi)


def symmetric_pupil(n_rays: int, *, azimuth_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Unit-disc points, uniform in area and mirror-symmetric about the field's meridian
    and about the axis across it.

    ``n // 4`` Vogel points (:func:`vogel_pupil`) folded into one quadrant (still uniform
    there) and mirrored into the other three, plus ``n mod 4`` points at the centre. A
    rotationally symmetric lens images a star's bundle symmetrically about the meridian,
    so the sagittal centroid is exactly zero; the mirror across it cancels the terms of
    the meridional centroid that are odd in the pupil coordinate (on axis it is zero too).
    """
    if n_rays < 1:
        raise LensError(f"n_rays: must be >= 1, got {n_rays}")
    m = n_rays // 4
    x, y = vogel_pupil(m) if m else (np.zeros(0), np.zeros(0))
    x, y = np.abs(x), np.abs(y)
    extra = np.zeros(n_rays - 4 * m)
    xs = np.concatenate([x, -x, x, -x, extra])
    ys = np.concatenate([y, y, -y, -y, extra])
    a = math.radians(azimuth_deg)
    if a == 0.0:
        return xs, ys
    ca, sa = math.cos(a), math.sin(a)
    return ca * xs - sa * ys, sa * xs + ca * ys


def field_bundle(prescription: Prescription, *, field_deg: float, n_rays: int,
                 para: ParaxialData | None = None, field_azimuth_deg: float = 0.0):
    """Parallel rays from a star at ``field_deg`` filling the paraxial entrance pupil.

    The star lies at angle ``field_deg`` from the axis towards azimuth
    ``field_azimuth_deg`` (0: the +x side); its light travels along
    ``d = (-sin(theta) cos(a), -sin(theta) sin(a), cos(theta))`` and images on the opposite
    side (an inverted image). Pupil points (:func:`symmetric_pupil`) lie on the entrance
    pupil plane; rays start on a plane in front of the first surface.

    Returns
    -------
    x, y, z, dx, dy, dz : ndarray (n_rays,)
    """
    if para is None:
        para = paraxial(prescription, wavelength_nm=prescription.analysis.reference_wavelength_nm)
    th = math.radians(float(field_deg))
    az = math.radians(float(field_azimuth_deg))
    d = np.array([-math.sin(th) * math.cos(az), -math.sin(th) * math.sin(az), math.cos(th)])
    px, py = symmetric_pupil(int(n_rays), azimuth_deg=field_azimuth_deg)
    rep = para.entrance_pupil_radius_mm
    z_ep = para.entrance_pupil_z_mm
    s0 = prescription.surfaces[0]
    front = -abs(float(s0.shape.sag(s0.semi_diameter_mm**2)))
    z0 = min(z_ep, front, 0.0) - 1.0
    t = (z0 - z_ep) / d[2]
    n = px.size
    return (rep * px + t * d[0], rep * py + t * d[1], np.full(n, z_ep + t * d[2]),
            np.full(n, d[0]), np.full(n, d[1]), np.full(n, d[2]))


def _drjit_ns():
    import drjit as dr

    return SimpleNamespace(sqrt=dr.sqrt, select=dr.select, abs=dr.abs, name="drjit")


def _refine_and_refract(xp, *, x, y, z, dx, dy, dz, t, shape: SurfaceShape, z_v: float,
                        semi_diameter_mm: float, mu, n_steps: int):
    """Refinement of Mitsuba's hit on the exact surface, aperture test, Snell refraction.

    Spheres and planes: the exact root of the surface's quadratic nearest Mitsuba's
    distance ``t`` (Mitsuba chose the sheet), in the numerically stable vertex form of
    Welford (Aberrations of Optical Systems, 1986, Sec. 4.3): with ``q`` the ray point
    relative to the vertex, ``B = d_z - c q.d``, ``G = c |q|^2 - 2 q_z``, the roots of
    ``c t^2 - 2 B t + G = 0`` are ``G / (B + sqrt(B^2 - c G))`` and ``(B + sqrt(...)) / c``;
    the unit normal is ``(-c q_x, -c q_y, 1 - c q_z)``. Conic and aspheric surfaces:
    ``n_steps`` Newton steps on ``z - z_v - sag(x^2 + y^2)`` from ``t``, normal from the sag
    gradient (:mod:`simcam.starcam.lens.surface`). Works on numpy or Dr.Jit arrays (``xp``).

    Returns the new point and direction and the masks ``converged`` (a finite hit on the
    surface, ahead of the ray), ``inside`` (within the semi-diameter) and ``tir`` (total
    internal reflection).
    """
    if shape.is_sphere:
        c = shape.curvature_per_mm
        qx, qy, qz = x, y, z - z_v
        b = dz - c * (qx * dx + qy * dy + qz * dz)
        g = c * (qx * qx + qy * qy + qz * qz) - 2.0 * qz
        root = b + xp.sqrt(b * b - c * g)
        t_near = g / root
        if c != 0.0:
            t_far = root / c
            t = xp.select(xp.abs(t_near - t) <= xp.abs(t_far - t), t_near, t_far)
        else:
            t = t_near
        px = x + t * dx
        py = y + t * dy
        pz = z + t * dz
        lz = pz - z_v
        resid = 0.5 * (c * (px * px + py * py + lz * lz) - 2.0 * lz)  # distance to the sphere, to first order
        nx = -c * px
        ny = -c * py
        nz = 1.0 - c * lz
        s = px * px + py * py
    else:
        for _ in range(n_steps):
            px = x + t * dx
            py = y + t * dy
            pz = z + t * dz
            s = px * px + py * py
            f = pz - z_v - shape.sag(s, xp)
            fp = dz - shape.dsag_ds(s, xp) * 2.0 * (px * dx + py * dy)
            t = t - f / fp
        px = x + t * dx
        py = y + t * dy
        pz = z + t * dz
        s = px * px + py * py
        resid = pz - z_v - shape.sag(s, xp)
        m = shape.dsag_ds(s, xp)
        nx = -2.0 * px * m
        ny = -2.0 * py * m
        inv = 1.0 / xp.sqrt(1.0 + nx * nx + ny * ny)
        nx = nx * inv
        ny = ny * inv
        nz = inv  # +z component: along the propagation of a forward ray
    converged = (xp.abs(resid) <= _CONVERGED_MM) & (t >= -_BACKOFF_MM * 1e-3) & (dz > 0.0)
    inside = s <= semi_diameter_mm * semi_diameter_mm
    cos_i = nx * dx + ny * dy + nz * dz
    k = 1.0 - mu * mu * (1.0 - cos_i * cos_i)
    tir = k < 0.0
    g = xp.sqrt(xp.select(tir, 0.0, k)) - mu * cos_i
    ndx = mu * dx + g * nx
    ndy = mu * dy + g * ny
    ndz = mu * dz + g * nz
    return px, py, pz, ndx, ndy, ndz, converged, inside, tir


class LensTracer:
    """Traces ray bundles through a prescription with Mitsuba 3 (see module docstring).

    Parameters
    ----------
    prescription : Prescription or str
        The lens, or a reference for :func:`~simcam.starcam.lens.prescription.load_prescription`.
    variant : {None, "llvm_ad_rgb", "scalar_rgb"}
        Mitsuba variant (None: vectorised if available, see :mod:`simcam.starcam.lens.backend`).
    """

    def __init__(self, prescription, *, variant: str | None = None):
        self.prescription = load_prescription(prescription)
        self.backend: Backend = get_backend(variant)
        self._z = self.prescription.vertex_z_mm
        self._shapes = [s.shape for s in self.prescription.surfaces]
        self._scenes = self._build_scenes()
        self._far_check = [self._may_meet_far_side(j) for j in range(len(self._shapes))]

    @property
    def variant(self) -> str:
        """The Mitsuba variant tracing the rays."""
        return self.backend.variant

    def _may_meet_far_side(self, j: int) -> bool:
        """Whether a ray can meet surface ``j``'s sphere first on its far hemisphere.

        Only a concave surface (``R < 0``, centre in front of the vertex) can be met so, by
        a ray starting outside its sphere or behind its centre. Rays start on the previous
        surface's clear aperture (the first surface: in front of the lens); if all of it
        lies inside the sphere and behind the centre (with margin), a forward ray leaves
        the sphere through the vertex-side cap and the re-query is skipped.
        """
        shape = self._shapes[j]
        if shape.curvature_per_mm >= 0.0:
            return False
        if j == 0:
            return True
        r = -1.0 / shape.curvature_per_mm
        zc = float(self._z[j]) - r
        prev = self.prescription.surfaces[j - 1]
        rho = np.linspace(0.0, prev.semi_diameter_mm, 65)
        zp = float(self._z[j - 1]) + self._shapes[j - 1].sag(rho * rho)
        margin = 10.0 * _BACKOFF_MM
        inside = np.all(np.hypot(rho, zp - zc) < r - margin) and np.all(zp - margin > zc)
        return not bool(inside)

    def _build_scenes(self):
        scenes = []
        with in_variant(self.backend.variant) as mi:
            for j, surf in enumerate(self.prescription.surfaces):
                z = float(self._z[j])
                c = surf.curvature_per_mm
                if c == 0.0:
                    a = surf.semi_diameter_mm * _DISK_MARGIN
                    tr = mi.ScalarTransform4f().translate([0.0, 0.0, z]).scale([a, a, 1.0])
                    shape = {"type": "disk", "to_world": tr}
                else:
                    r = 1.0 / c
                    shape = {"type": "sphere", "center": [0.0, 0.0, z + r], "radius": abs(r)}
                scenes.append(mi.load_dict({"type": "scene", f"surface_{j}": shape}))
        return scenes

    # ------------------------------------------------------------------ public
    def trace(self, *, x_mm, y_mm, z_mm, dx, dy, dz, wavelength_nm, record_path: bool = False) -> TraceResult:
        """Trace rays (object-space starting points and unit directions) to image space.

        Parameters
        ----------
        x_mm, y_mm, z_mm : array_like (N,)
            Starting points, in front of the first surface, mm.
        dx, dy, dz : array_like (N,)
            Unit directions (``dz > 0``).
        wavelength_nm : float or array_like (N,)
            Wavelength of the bundle, or of each ray (a few distinct values: several
            monochromatic bundles traced in one pass), nm.
        record_path : bool
            Keep the point of every ray on every surface (:attr:`TraceResult.path_mm`).

        Returns
        -------
        TraceResult
        """
        arrs = [np.ascontiguousarray(np.asarray(a, dtype=np.float64)).ravel() for a in (x_mm, y_mm, z_mm, dx, dy, dz)]
        n = arrs[0].size
        if any(a.size != n for a in arrs):
            raise LensError("trace: x_mm, y_mm, z_mm, dx, dy, dz must have the same length")
        if not all(np.all(np.isfinite(a)) for a in arrs):
            raise LensError("trace: ray coordinates must be finite")
        wl = np.asarray(wavelength_nm, dtype=np.float64)
        if wl.ndim == 0:
            uniq, inv = wl.reshape(1), np.zeros(n, dtype=np.uint32)
        else:
            wl = wl.ravel()
            if wl.size != n:
                raise LensError(f"trace: wavelength_nm has {wl.size} values for {n} rays")
            uniq, inv = np.unique(wl, return_inverse=True)
        return self._trace_indexed(arrs, uniq, inv.astype(np.uint32), wl if wl.ndim else float(wl),
                                   record_path=record_path)

    def _trace_indexed(self, arrs, wavelengths_nm: np.ndarray, wl_index: np.ndarray, wl_attr, *,
                       record_path: bool = False) -> TraceResult:
        """Trace with ``wavelengths_nm[wl_index[i]]`` the wavelength of ray ``i`` (validated inputs)."""
        if not np.all(np.isfinite(wavelengths_nm)) or np.any(wavelengths_nm <= 0):
            raise LensError(f"trace: wavelengths must be finite and > 0, got {wavelengths_nm}")
        idx = self.prescription.indices(wavelengths_nm)  # (n_surfaces + 1, n_wavelengths)
        mus = idx[:-1] / idx[1:]  # (n_surfaces, n_wavelengths): n / n' at every surface
        path = [] if record_path else None
        if self.backend.vectorised:
            out = self._trace_llvm(arrs, mus, wl_index, path)
        else:
            out = self._trace_scalar(arrs, mus, wl_index, path)
        x, y, z, ddx, ddy, ddz, lost = out
        return TraceResult(x_mm=x, y_mm=y, z_mm=z, dx=ddx, dy=ddy, dz=ddz, alive=lost == 0,
                           lost_code=lost, wavelength_nm=wl_attr, n_surfaces=len(self._shapes),
                           path_mm=None if path is None else np.array(path))

    # ------------------------------------------------------------------ llvm
    def _trace_llvm(self, arrs, mus, inv, path):
        import drjit as dr

        _, T = self.backend.mitsuba()
        F64 = T.Float64
        single = mus.shape[1] == 1
        wl_index = None if single else T.UInt32(inv)
        xp = _drjit_ns()
        x, y, z, dx, dy, dz = (F64(a) for a in arrs)
        n = arrs[0].size
        alive = dr.full(T.Bool, True, n)
        lost = dr.zeros(T.UInt32, n)
        for j, (shape, scene) in enumerate(zip(self._shapes, self._scenes)):
            surf = self.prescription.surfaces[j]
            z_v = float(self._z[j])
            # opaque: a parameter of the compiled kernel, not a literal (kernels are reused)
            mu = dr.opaque(F64, float(mus[j, 0])) if single else dr.gather(F64, F64(mus[j]), wl_index)
            f32 = T.Float
            ray = T.Ray3f(
                T.Point3f(f32(x - _BACKOFF_MM * dx), f32(y - _BACKOFF_MM * dy), f32(z - _BACKOFF_MM * dz)),
                T.Vector3f(f32(dx), f32(dy), f32(dz)),
            )
            pi = scene.ray_intersect_preliminary(ray, active=alive)
            hit = alive & pi.is_valid()
            t = F64(pi.t) - _BACKOFF_MM
            if self._far_check[j]:
                # a concave surface (centre in front) can be met first on the far side of its
                # sphere by a ray starting outside the sphere; a convex one cannot (its cap is
                # the near side, and a forward ray starts in front of it)
                r = 1.0 / shape.curvature_per_mm
                zc = z_v + r
                far = hit & ((z + t * dz - zc) * r > 0.0)  # hit on the hemisphere away from the vertex
                if dr.any(far):
                    eps = 1e-3
                    ray2 = T.Ray3f(
                        T.Point3f(f32(x + (t + eps) * dx), f32(y + (t + eps) * dy), f32(z + (t + eps) * dz)),
                        T.Vector3f(f32(dx), f32(dy), f32(dz)),
                    )
                    pi2 = scene.ray_intersect_preliminary(ray2, active=far)
                    t = dr.select(far, t + eps + F64(pi2.t), t)
                    hit = dr.select(far, pi2.is_valid(), hit) & alive
            px, py, pz, ndx, ndy, ndz, conv, inside, tir = _refine_and_refract(
                xp, x=x, y=y, z=z, dx=dx, dy=dy, dz=dz, t=t, shape=shape, z_v=z_v,
                semi_diameter_mm=surf.semi_diameter_mm, mu=mu, n_steps=_newton_steps(shape),
            )
            ok = hit & conv & dr.isfinite(px) & dr.isfinite(py) & dr.isfinite(ndz)
            base = 1 + 3 * j
            lost = dr.select(alive & ~ok, base + 0, lost)
            a1 = alive & ok
            lost = dr.select(a1 & ~inside, base + 1, lost)
            a2 = a1 & inside
            lost = dr.select(a2 & tir, base + 2, lost)
            alive = a2 & ~tir
            x = dr.select(alive, px, x)
            y = dr.select(alive, py, y)
            z = dr.select(alive, pz, z)
            dx = dr.select(alive, ndx, dx)
            dy = dr.select(alive, ndy, dy)
            dz = dr.select(alive, ndz, dz)
            dr.eval(x, y, z, dx, dy, dz, alive, lost)
            if path is not None:
                path.append([np.array(v.numpy(), copy=True) for v in (x, y, z)])
        # .numpy() views the evaluated Dr.Jit buffer (the view keeps it alive): no copy
        return tuple(v.numpy() for v in (x, y, z, dx, dy, dz, lost))

    # ------------------------------------------------------------------ scalar fallback
    def _trace_scalar(self, arrs, mus, inv, path):
        _, T = self.backend.mitsuba()
        x, y, z, dx, dy, dz = (a.copy() for a in arrs)
        n = x.size
        alive = np.ones(n, dtype=bool)
        lost = np.zeros(n, dtype=np.uint32)
        for j, (shape, scene) in enumerate(zip(self._shapes, self._scenes)):
            surf = self.prescription.surfaces[j]
            z_v = float(self._z[j])
            t = np.zeros(n)
            hit = np.zeros(n, dtype=bool)
            r = 1.0 / shape.curvature_per_mm if self._far_check[j] else None
            for i in np.flatnonzero(alive):
                o = T.Point3f(x[i] - _BACKOFF_MM * dx[i], y[i] - _BACKOFF_MM * dy[i], z[i] - _BACKOFF_MM * dz[i])
                d = T.Vector3f(dx[i], dy[i], dz[i])
                pi = scene.ray_intersect_preliminary(T.Ray3f(o, d))
                if not pi.is_valid():
                    continue
                ti = float(pi.t) - _BACKOFF_MM
                if r is not None and (z[i] + ti * dz[i] - (z_v + r)) * r > 0.0:
                    eps = 1e-3
                    o2 = T.Point3f(x[i] + (ti + eps) * dx[i], y[i] + (ti + eps) * dy[i], z[i] + (ti + eps) * dz[i])
                    pi2 = scene.ray_intersect_preliminary(T.Ray3f(o2, d))
                    if not pi2.is_valid():
                        continue
                    ti = ti + eps + float(pi2.t)
                t[i] = ti
                hit[i] = True
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                px, py, pz, ndx, ndy, ndz, conv, inside, tir = _refine_and_refract(
                    NUMPY, x=x, y=y, z=z, dx=dx, dy=dy, dz=dz, t=t, shape=shape, z_v=z_v,
                    semi_diameter_mm=surf.semi_diameter_mm, mu=mus[j][inv], n_steps=_newton_steps(shape),
                )
                ok = hit & conv & np.isfinite(px) & np.isfinite(py) & np.isfinite(ndz)
            base = 1 + 3 * j
            lost[alive & ~ok] = base + 0
            a1 = alive & ok
            lost[a1 & ~inside] = base + 1
            a2 = a1 & inside
            lost[a2 & tir] = base + 2
            alive = a2 & ~tir
            x = np.where(alive, px, x)
            y = np.where(alive, py, y)
            z = np.where(alive, pz, z)
            dx = np.where(alive, ndx, dx)
            dy = np.where(alive, ndy, dy)
            dz = np.where(alive, ndz, dz)
            if path is not None:
                path.append([x.copy(), y.copy(), z.copy()])
        return x, y, z, dx, dy, dz, lost
