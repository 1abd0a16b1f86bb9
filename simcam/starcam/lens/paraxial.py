"""Paraxial optics of a prescription by ray-transfer (ABCD) matrices.

Rays are ``(y, n u)``: height (mm) and reduced slope (index times slope), so every
matrix has determinant 1 (A. Gerrard and J. M. Burch, Introduction to Matrix Methods in
Optics, Wiley 1975, ch. III; also Hecht, Optics, Sec. 6.2). With ``c = 1/R``::

    refraction from index n to n':   [[1, 0], [-(n' - n) c, 1]]
    transfer over t in index n:      [[1, t / n], [0, 1]]

For a system matrix ``[[A, B], [C, D]]`` from the first surface to the last (object and
image in air): effective focal length ``f' = -1 / C``, back focal distance (last vertex
to the rear focal point) ``BFD = -A / C``. The entrance pupil is the stop imaged by the
surfaces before it: its radius is ``a_stop / A_s`` and its position ``z_EP = B_s n_0 / A_s``
(from the first vertex), where ``[[A_s, B_s], ...]`` maps the first vertex plane to the
stop. A chief ray of object-space slope ``u`` passes the entrance pupil centre; its
height at surface ``j`` per unit ``u`` is tabulated in :attr:`ParaxialData.chief_height_per_slope_mm`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simcam.starcam.lens.errors import LensError

__all__ = ["ParaxialData", "paraxial", "refraction_matrix", "transfer_matrix"]


def refraction_matrix(*, n_before: float, n_after: float, curvature_per_mm: float) -> np.ndarray:
    """ABCD matrix of refraction at a surface of curvature ``c`` from index ``n`` to ``n'``."""
    return np.array([[1.0, 0.0], [-(n_after - n_before) * curvature_per_mm, 1.0]])


def transfer_matrix(*, thickness_mm: float, index: float) -> np.ndarray:
    """ABCD matrix of a transfer over ``thickness_mm`` in a medium of ``index`` (reduced slopes)."""
    return np.array([[1.0, thickness_mm / index], [0.0, 1.0]])


@dataclass(frozen=True)
class ParaxialData:
    """First-order properties at one wavelength (lengths in mm, object at infinity).

    Attributes
    ----------
    wavelength_nm : float
    efl_mm : float
        Effective focal length ``-1/C``.
    bfd_mm : float
        Back focal distance: last vertex to the paraxial focus, ``-A/C``.
    entrance_pupil_z_mm : float
        Entrance pupil position from the first vertex (along +z).
    entrance_pupil_radius_mm : float
    f_number : float
        ``efl / (2 * entrance_pupil_radius)``.
    marginal_height_mm : ndarray
        Height of the marginal ray (parallel, at the pupil edge) at each surface.
    chief_height_per_slope_mm : ndarray
        Height at each surface of the chief ray per unit object-space slope ``u`` (mm),
        and, as the last element, at the paraxial image plane: the focal length (the
        image of a parallel beam of slope ``u`` is at height ``f' u``).
    system_matrix : ndarray (2, 2)
    """

    wavelength_nm: float
    efl_mm: float
    bfd_mm: float
    entrance_pupil_z_mm: float
    entrance_pupil_radius_mm: float
    f_number: float
    marginal_height_mm: np.ndarray
    chief_height_per_slope_mm: np.ndarray
    system_matrix: np.ndarray


def paraxial(prescription, *, wavelength_nm: float) -> ParaxialData:
    """Paraxial (ABCD) data of ``prescription`` at ``wavelength_nm``.

    Raises
    ------
    LensError
        An afocal system (``C = 0``) or a stop that the preceding surfaces image to
        infinity (``A_s = 0``).
    """
    surfs = prescription.surfaces
    n = prescription.indices([wavelength_nm])[:, 0]  # n[0]: object space, n[j + 1]: after surface j
    mats_at = []  # matrix from the first vertex plane (just before refraction) to just before surface j
    m = np.eye(2)
    for j, s in enumerate(surfs):
        mats_at.append(m.copy())
        m = refraction_matrix(n_before=n[j], n_after=n[j + 1], curvature_per_mm=s.curvature_per_mm) @ m
        if j < len(surfs) - 1:
            m = transfer_matrix(thickness_mm=s.thickness_mm, index=n[j + 1]) @ m
    system = m  # first vertex (before refraction) -> last vertex (after refraction)
    a = system[0, 0]
    c = system[1, 0]
    if c == 0.0:
        raise LensError(f"{prescription.name}: the system is afocal at {wavelength_nm:g} nm (C = 0)")
    n_img = n[-1]
    efl = -n_img / c
    bfd = -a * n_img / c
    s_idx = prescription.stop_index
    ms = mats_at[s_idx]
    if ms[0, 0] == 0.0:
        raise LensError(f"{prescription.name}: surfaces before the stop image it to infinity")
    a_stop = surfs[s_idx].semi_diameter_mm
    ep_radius = a_stop / ms[0, 0]
    # chief ray: y1 + ... passes the stop centre: y_s = A_s y1 + B_s (n0 u) = 0
    heights_m = np.array([(mk @ np.array([abs(ep_radius), 0.0]))[0] for mk in mats_at])
    y1_per_u = -ms[0, 1] * n[0] / ms[0, 0]
    ep_z = -y1_per_u  # the object-space chief ray y1 + u z crosses the axis at z = -y1/u
    heights_c = np.array([(mk @ np.array([y1_per_u, n[0] * 1.0]))[0] for mk in mats_at])
    # chief ray at the paraxial image plane (BFD behind the last vertex)
    out = system @ np.array([y1_per_u, n[0] * 1.0])
    y_img = out[0] + bfd * out[1] / n_img
    return ParaxialData(
        wavelength_nm=float(wavelength_nm), efl_mm=float(efl), bfd_mm=float(bfd),
        entrance_pupil_z_mm=float(ep_z), entrance_pupil_radius_mm=float(abs(ep_radius)),
        f_number=float(abs(efl) / (2.0 * abs(ep_radius))), marginal_height_mm=heights_m,
        chief_height_per_slope_mm=np.append(heights_c, y_img), system_matrix=system,
    )
