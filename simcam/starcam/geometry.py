"""Focal-plane geometry of the chip mosaic.

Chips of ``chip_cols x chip_rows`` pixels sit side by side along the focal-plane ``u``
axis, ``gap_px`` apart, each with its own placement error (offset, rotation about its
centre). The mosaic *array* concatenates the chips' pixel arrays along columns (chip
``k`` occupies columns ``k*chip_cols .. (k+1)*chip_cols-1``), so the gap does not appear in
mosaic pixel coordinates (see docs/conventions.md).

For chip ``k`` with centre ``c_k`` (focal px) and rotation ``theta_k`` the rigid map is

    (u, v) = c_k + R(theta_k) (x_c - x_0, y_c - y_0),    x_0 = (cols-1)/2, y_0 = (rows-1)/2,

with ``(x_c, y_c)`` chip pixel coordinates and ``R`` the counter-clockwise rotation
(from +x toward +y). Nominal centres: ``c_k = ((k - (n-1)/2)(cols + gap), 0)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from simcam.starcam.scenario import DetectorModel


@dataclass(frozen=True)
class Mosaic:
    """Rigid placement of each chip in the focal plane (see module docstring)."""

    chip_cols: int
    chip_rows: int
    center_u_px: np.ndarray
    center_v_px: np.ndarray
    rotation_rad: np.ndarray

    @classmethod
    def from_model(cls, det: DetectorModel) -> Mosaic:
        """Build from a scenario's detector section."""
        n = det.n_chips
        k = np.arange(n, dtype=float)
        cu = (k - (n - 1) / 2.0) * (det.chip_cols + det.gap_px)
        cu = cu + np.array([c.offset_x_px for c in det.chips])
        cv = np.array([c.offset_y_px for c in det.chips], dtype=float)
        rot = np.deg2rad(np.array([c.rotation_deg for c in det.chips], dtype=float))
        return cls(det.chip_cols, det.chip_rows, cu, cv, rot)

    @property
    def n_chips(self) -> int:
        """Number of chips."""
        return len(self.center_u_px)

    @property
    def shape(self) -> tuple[int, int]:
        """Mosaic array shape (rows, cols)."""
        return self.chip_rows, self.chip_cols * self.n_chips

    @cached_property
    def _rotation_cos_sin(self) -> tuple[np.ndarray, np.ndarray]:
        """``cos`` and ``sin`` of each chip's rotation (computed on first use; the fields are
        not changed after construction)."""
        return np.cos(self.rotation_rad), np.sin(self.rotation_rad)

    def _chip_coords(self, u, v, k):
        """Chip ``k``'s pixel coordinates of focal points (no bounds check); ``k`` an int, or
        an int array of one chip per point."""
        x0 = (self.chip_cols - 1) / 2.0
        y0 = (self.chip_rows - 1) / 2.0
        du = u - self.center_u_px[k]
        dv = v - self.center_v_px[k]
        cos, sin = self._rotation_cos_sin
        c, s = cos[k], sin[k]
        return x0 + c * du + s * dv, y0 - s * du + c * dv

    def focal_to_chip(self, u_px, v_px, *, margin_px: float = 0.0):
        """Map focal-plane points to (chip, x_chip, y_chip).

        A point lands on chip ``k`` if it is at least ``margin_px`` inside the chip's pixel
        area ``[-0.5, cols-0.5) x [-0.5, rows-0.5)``; otherwise its chip is -1.

        Returns
        -------
        chip : ndarray of int
        x_chip, y_chip : ndarray of float
            Chip pixel coordinates (pixel centres at integers); NaN where chip is -1.
        """
        u = np.atleast_1d(np.asarray(u_px, dtype=float))
        v = np.atleast_1d(np.asarray(v_px, dtype=float))
        chip = np.full(u.shape, -1, dtype=int)
        xc = np.full(u.shape, np.nan)
        yc = np.full(u.shape, np.nan)
        for k in range(self.n_chips):
            x, y = self._chip_coords(u, v, k)
            inside = (
                (x >= -0.5 + margin_px)
                & (x < self.chip_cols - 0.5 - margin_px)
                & (y >= -0.5 + margin_px)
                & (y < self.chip_rows - 0.5 - margin_px)
                & (chip < 0)
            )
            chip[inside] = k
            xc[inside] = x[inside]
            yc[inside] = y[inside]
        return chip, xc, yc

    def chip_to_focal(self, chip, x_chip, y_chip):
        """Inverse of :meth:`focal_to_chip`: chip pixel coordinates to focal (u, v) px."""
        chip = np.asarray(chip, dtype=int)
        x = np.asarray(x_chip, dtype=float) - (self.chip_cols - 1) / 2.0
        y = np.asarray(y_chip, dtype=float) - (self.chip_rows - 1) / 2.0
        c, s = np.cos(self.rotation_rad[chip]), np.sin(self.rotation_rad[chip])
        return self.center_u_px[chip] + c * x - s * y, self.center_v_px[chip] + s * x + c * y

    def vector_to_chip(self, du_px, dv_px, chip):
        """Rotate a focal-plane displacement into chip pixel axes (for lateral-colour shifts)."""
        chip = np.asarray(chip, dtype=int)
        cos, sin = self._rotation_cos_sin
        c, s = cos[chip], sin[chip]
        # broadcast chip over trailing axes of du/dv
        while c.ndim < np.ndim(du_px):
            c, s = c[..., None], s[..., None]
        return c * du_px + s * dv_px, -s * du_px + c * dv_px

    def chip_to_mosaic_x(self, chip, x_chip):
        """Mosaic column coordinate of chip pixel coordinate ``x_chip``."""
        return np.asarray(chip) * self.chip_cols + np.asarray(x_chip, dtype=float)

    def mosaic_to_chip(self, x_mosaic, y_mosaic):
        """Mosaic pixel coordinates to (chip, x_chip, y_chip)."""
        x = np.asarray(x_mosaic, dtype=float)
        chip = np.floor((x + 0.5) / self.chip_cols).astype(int)
        return chip, x - chip * self.chip_cols, np.asarray(y_mosaic, dtype=float)

    def mosaic_to_focal(self, x_mosaic, y_mosaic):
        """Mosaic pixel coordinates to focal-plane (u, v) px."""
        chip, xc, yc = self.mosaic_to_chip(x_mosaic, y_mosaic)
        return self.chip_to_focal(chip, xc, yc)

    def focal_to_mosaic(self, u_px, v_px, *, margin_px: float = 0.0):
        """Focal (u, v) to mosaic (x, y); NaN off the chips. Returns chip, x, y."""
        chip, xc, yc = self.focal_to_chip(u_px, v_px, margin_px=margin_px)
        x = np.where(chip >= 0, chip * self.chip_cols + xc, np.nan)
        return chip, x, yc
