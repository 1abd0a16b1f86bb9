"""The correlation length of the attitude study's smooth-field residual map
(``budget.lsfe_c_correlation_px``, docs/attitude.md "The correlation length").

The flown camera's distortion seen through its onboard correction on a 41 x 21 grid over the
mosaic (what the lab's distortion calibration maps; no colour, no noise), mean removed; its
empirical isotropic correlogram (pairs in 50 px bins, x and y averaged) and the length ``L``
of the Gaussian correlogram ``exp(-d^2 / (2 L^2))`` that fits it best (least squares over the
bins below 1,600 px), in the seed's own world and the realistic one.

    PYTHONPATH=. python benchmarks/attitude_correlogram.py
"""

import numpy as np
from scipy.optimize import minimize_scalar

from budget.attitude.study import STUDY
from budget.runner.claims import world_scenario
from simcam.starcam.render import StarCamera


def _misfit(length: float, d_px: np.ndarray, rho: np.ndarray) -> float:
    """Sum of squares of the correlogram ``rho`` at ``d_px`` less ``exp(-d^2 / (2 L^2))``."""
    return float(np.sum((rho - np.exp(-0.5 * (d_px / length) ** 2)) ** 2))


def main() -> None:
    for world in ("seed", "realistic"):
        scn = world_scenario(STUDY, STUDY.load_scenario(None), world)
        cam = StarCamera(scn.camera_scenario)
        det = scn.camera_scenario.detector
        width = det.n_chips * det.chip_cols + (det.n_chips - 1) * det.gap_px
        u, v = np.meshgrid(np.linspace(-0.48 * width, 0.48 * width, 41),
                           np.linspace(-0.48 * det.chip_rows, 0.48 * det.chip_rows, 21))
        u, v = u.ravel(), v.ravel()
        ud, vd = cam.distortion.forward(u_px=u, v_px=v)
        _, mx, my = cam.mosaic.focal_to_mosaic(ud, vd)
        _, ix, iy = cam.mosaic.focal_to_mosaic(u, v)
        rx, ry = cam.report_positions(mx, my)
        ex, ey = rx - ix, ry - iy
        ok = np.isfinite(ex) & np.isfinite(ix)
        u, v, ex, ey = u[ok], v[ok], ex[ok] - np.mean(ex[ok]), ey[ok] - np.mean(ey[ok])
        d = np.hypot(u[:, None] - u[None, :], v[:, None] - v[None, :])
        prod = (ex[:, None] * ex[None, :] + ey[:, None] * ey[None, :]) / 2
        var = np.mean((ex**2 + ey**2) / 2)
        bins = np.arange(0, 1600, 50.0)
        idx = np.digitize(d.ravel(), bins)
        rho = np.array([prod.ravel()[idx == k].mean() / var for k in range(1, len(bins))])
        mid = bins[:-1] + 25
        fit = minimize_scalar(_misfit, args=(mid, rho), bounds=(10, 5000), method="bounded")
        print(f"{world}: {ok.sum()} points, rms {np.sqrt(var):.4f} px, L {fit.x:.0f} px; correlogram at "
              + ", ".join(f"{m:.0f}: {r:.2f}" for m, r in zip(mid[:10], rho[:10])))


if __name__ == "__main__":
    main()
