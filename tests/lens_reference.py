"""Plain-numpy reference sequential ray tracer, written only for the tests of simcam.starcam.lens.

It shares no code with ``simcam.starcam.lens`` (no Mitsuba, no Dr.Jit, its own sag, intersection
and refraction formulas), so agreement with the Mitsuba tracer is an independent check.

* Sphere / plane intersection in the vertex-referenced closed form (W. T. Welford,
  Aberrations of Optical Systems, Adam Hilger 1986, Sec. 4.3; the numerically stable root
  of ``c (x^2 + y^2 + z^2) - 2 z = 0`` that lies on the vertex-side cap)::

      t = G / (B + sqrt(B^2 - c G)),   B = d_z - c (p . d),   G = c |p|^2 - 2 p_z

  with ``p`` the ray point relative to the vertex.
* Conic and aspheric surfaces: Newton's method on the implicit surface, started from the
  base-sphere solution, iterated until the step is below 1e-15 mm (at most 100 steps).
* Refraction: the tangential component of ``n d`` is conserved,
  ``n' d'_t = n d_t`` and ``d'_n = sqrt(1 - |d'_t|^2)`` (Snell's law, Born & Wolf,
  Principles of Optics, Sec. 1.5).
"""

from __future__ import annotations

import math

import numpy as np


def sellmeier_index(b, c_um2, wavelength_nm):
    """n from the three-term Sellmeier formula (lambda in um, C in um^2)."""
    lam2 = (wavelength_nm / 1000.0) ** 2
    return math.sqrt(1.0 + sum(bi * lam2 / (lam2 - ci) for bi, ci in zip(b, c_um2)))


def _sag(s, c, k, coeffs):
    """z(s) of the even asphere, written as (1 - sqrt(1 - (1+k)c^2 s)) / ((1+k) c) when possible."""
    kk = (1.0 + k)
    if c == 0.0:
        z = np.zeros_like(s)
    elif kk == 0.0:
        z = 0.5 * c * s  # paraboloid
    else:
        z = c * s / (1.0 + np.sqrt(1.0 - kk * c * c * s))
    for i, a in enumerate(coeffs):
        z = z + a * s ** (i + 2)
    return z


def _dsag(s, c, k, coeffs):
    kk = 1.0 + k
    d = np.zeros_like(s) if c == 0.0 else c / (2.0 * np.sqrt(1.0 - kk * c * c * s))
    for i, a in enumerate(coeffs):
        d = d + (i + 2) * a * s ** (i + 1)
    return d


def trace(surfaces, indices, x, y, z, dx, dy, dz):
    """Trace rays through ``surfaces`` (dicts: z_mm, c, k, coeffs, sd) with ``indices``
    (object space first, one more than surfaces).

    Returns the points on every surface (list of (x, y, z) arrays), the final directions
    and a boolean mask of rays that passed every clear aperture without TIR.
    """
    x, y, z, dx, dy, dz = (np.array(a, dtype=np.float64) for a in (x, y, z, dx, dy, dz))
    ok = np.ones(x.shape, dtype=bool)
    path = []
    for j, s in enumerate(surfaces):
        c, k, coeffs = s["c"], s["k"], s["coeffs"]
        px, py, pz = x, y, z - s["z_mm"]
        b = dz - c * (px * dx + py * dy + pz * dz)
        g = c * (px * px + py * py + pz * pz) - 2.0 * pz
        disc = b * b - c * g
        with np.errstate(invalid="ignore"):
            t = g / (b + np.sqrt(disc))
        ok &= disc >= 0
        if k != 0.0 or coeffs:
            for _ in range(100):
                qx, qy, qz = px + t * dx, py + t * dy, pz + t * dz
                s2 = qx * qx + qy * qy
                f = qz - _sag(s2, c, k, coeffs)
                fp = dz - _dsag(s2, c, k, coeffs) * 2.0 * (qx * dx + qy * dy)
                step = f / fp
                t = t - step
                if np.all(np.abs(step[ok]) < 1e-15):
                    break
        qx, qy, qz = px + t * dx, py + t * dy, pz + t * dz
        s2 = qx * qx + qy * qy
        ok &= s2 <= s["sd"] ** 2
        m = _dsag(s2, c, k, coeffs)
        nx, ny, nz = -2.0 * qx * m, -2.0 * qy * m, np.ones_like(qx)
        norm = np.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx / norm, ny / norm, nz / norm
        n1, n2 = indices[j], indices[j + 1]
        dn = dx * nx + dy * ny + dz * nz
        tx, ty, tz = (n1 / n2) * (dx - dn * nx), (n1 / n2) * (dy - dn * ny), (n1 / n2) * (dz - dn * nz)
        tt = tx * tx + ty * ty + tz * tz
        ok &= tt <= 1.0
        with np.errstate(invalid="ignore"):
            root = np.sqrt(1.0 - tt)
        dx, dy, dz = tx + root * nx, ty + root * ny, tz + root * nz
        x, y, z = qx, qy, qz + s["z_mm"]
        path.append((x.copy(), y.copy(), z.copy()))
    return path, (dx, dy, dz), ok


def surfaces_from_prescription_dict(data):
    """Surfaces and a function of wavelength giving the indices, from the parsed TOML dict.

    Uses the glass coefficients passed in ``data["_glass_coeffs"]`` ({name: (B, C)}),
    so that the test supplies catalogue numbers independently of simcam.starcam.lens.glass.
    """
    zs = 0.0
    out = []
    for s in data["surfaces"]:
        r = s["radius_mm"]
        out.append({"z_mm": zs, "c": 0.0 if math.isinf(r) else 1.0 / r, "k": s.get("conic", 0.0),
                    "coeffs": list(s.get("aspheric_coeffs", [])), "sd": s["semi_diameter_mm"]})
        zs += s["thickness_mm"]
    glasses = ["air"] + [s.get("glass", "air") for s in data["surfaces"]]
    coeffs = data["_glass_coeffs"]

    def indices(wavelength_nm):
        return [1.0 if g.lower() == "air" else sellmeier_index(*coeffs[g.upper()], wavelength_nm) for g in glasses]

    return out, indices


#: Sellmeier coefficients (B1..B3, C1..C3 in um^2) typed from the data sheets (SCHOTT
#: optical glass data sheets; Malitson 1963 for CaF2, 1965 for fused silica), for the
#: reference tracer: the tests do not take them from simcam.starcam.lens.glass.
GLASS_COEFFS = {
    "N-BK7": ((1.03961212, 0.231792344, 1.01046945), (0.00600069867, 0.0200179144, 103.560653)),
    "F2": ((1.34533359, 0.209073176, 0.937357162), (0.00997743871, 0.0470450767, 111.886764)),
    "N-LAK9": ((1.46231905, 0.344399589, 1.15508372), (0.00724270156, 0.0243353131, 85.4686868)),
    "N-SF5": ((1.52481889, 0.187085527, 1.42729015), (0.011254756, 0.0588995392, 129.141675)),
    "N-SF6": ((1.77931763, 0.338149866, 2.08734474), (0.0133714182, 0.0617533621, 174.01759)),
    "CAF2": ((0.5675888, 0.4710914, 3.8484723), (0.050263605**2, 0.1003909**2, 34.649040**2)),
    "F_SILICA": ((0.6961663, 0.4079426, 0.8974794), (0.0684043**2, 0.1162414**2, 9.896161**2)),
}
