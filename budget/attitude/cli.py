"""The attitude study's own commands besides the runner's ``validate``, ``robustness`` and
``scenario``: ``budget attitude solve``, the attitude of a sky frame
(:mod:`budget.attitude.frame_solve`)."""

from __future__ import annotations

import click

from budget.attitude.frame_solve import (
    attitude_angles,
    attitude_from_angles,
    solve_sky_frame,
    tetra3_prior,
)
from simcam.infra.cli import write_json_atomic
from simcam.infra.errors import UserInputError
from simcam.infra.outputs import check_run_outputs
from simcam.io import read_frame
from simcam.limits import check_epoch_utc
from simcam.starcam import scenario as starcam_scenario
from simcam.starcam.render import StarCamera
from simcam.starcam.sky_view import sky_stars

__all__ = ["commands", "solve_command"]


def _prior(text: str | None):
    if text is None:
        return None
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3:
        raise UserInputError(f"--prior: expected RA,DEC,ROLL in degrees (three numbers), got {text!r}")
    return attitude_from_angles(*values)


def _epoch(given: str | None, header) -> str:
    value = given if given is not None else header.get("DATE-OBS")
    if value is None:
        raise UserInputError("--epoch: the frame's header has no DATE-OBS; give the epoch (ISO UTC)")
    try:
        return check_epoch_utc(str(value))
    except ValueError as exc:
        raise UserInputError(f"--epoch: {exc} (got {value!r})") from None


def solve_command() -> click.Command:
    @click.command("solve", help="The attitude of a sky FRAME (FITS) taken by the camera of a star-camera "
                                 "scenario: stars detected and centroided, reported through the camera's "
                                 "correction, identified against the Hipparcos stars near a prior attitude, "
                                 "solved by weighted least squares; writes the attitude, its covariance and "
                                 "the per-star residuals.")
    @click.argument("frame", type=click.Path(dir_okay=False))
    @click.option("--camera", "camera_ref", required=True,
                  help="The star camera: a scenario file or embedded:NAME (default, seed000_noisy, seed000_ideal).")
    @click.option("--prior", default=None, help="Coarse attitude RA,DEC,ROLL in degrees (boresight and roll: "
                                                "Rz(ra) Ry(90 - dec) Rz(roll)); without it, a lost-in-space "
                                                "solve with cedar-solve's tetra3 and --tetra3-database.")
    @click.option("--tetra3-database", default=None, type=click.Path(dir_okay=False),
                  help="A tetra3 pattern database for this camera's field (lost in space, no --prior).")
    @click.option("--epoch", default=None, help="Epoch of the frame (ISO UTC; default the header's DATE-OBS).")
    @click.option("--v-max", "v_max", type=click.FloatRange(-2.0, 14.0), default=7.5, show_default=True,
                  help="The catalogue's limit (V) for the identification.")
    @click.option("--match-radius", "match_radius", type=click.FloatRange(min=1.0, max=36000.0), default=600.0,
                  show_default=True, help="How far (arcsec) a star may lie from the prior's prediction.")
    @click.option("--sigma-px", "sigma_px", type=click.FloatRange(min=0.0, min_open=True), default=None,
                  help="Centroid error (px, 1 sigma) of the weights and covariance; default: from the residuals.")
    @click.option("--threshold-sigma", type=click.FloatRange(min=1.0, max=1000.0), default=5.0, show_default=True,
                  help="Detection threshold in the frame's noise sigmas.")
    @click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the solution as JSON.")
    def cmd(frame, camera_ref, prior, tetra3_database, epoch, v_max, match_radius, sigma_px, threshold_sigma,
            json_out):
        from astropy.time import Time

        check_run_outputs(json_out=json_out, inputs=(frame,))  # before the work
        image, header = read_frame(frame)
        camera = StarCamera(starcam_scenario.load(camera_ref))
        t = Time(_epoch(epoch, header), scale="utc")
        att = _prior(prior)
        if att is None:
            if tetra3_database is None:
                raise UserInputError("--prior: give a coarse attitude RA,DEC,ROLL, or --tetra3-database for a "
                                     "lost-in-space solve")
            att = tetra3_prior(image, camera, database=tetra3_database, threshold_sigma=threshold_sigma)
        sky = sky_stars(camera, t, catalogue_v_max_mag=v_max)
        sol = solve_sky_frame(image, camera, sky, att, match_radius_arcsec=match_radius, sigma_px=sigma_px,
                              threshold_sigma=threshold_sigma)
        ra, dec, roll = attitude_angles(sol.solution.attitude)
        s = sol.solution.sigma_arcsec
        click.echo(f"{sol.hip.size} of {sol.detected} stars identified; RA {ra:.6f} deg, Dec {dec:.6f} deg, "
                   f"roll {roll:.6f} deg; 1 sigma x {s[0]:.3f}\", y {s[1]:.3f}\", roll {s[2]:.2f}\" "
                   f"(centroid error {sol.sigma_px:.4f} px, {sol.sigma_source})")
        if json_out:
            write_json_atomic(json_out, {"frame": str(frame), "camera": camera_ref, "epoch_utc": t.isot,
                                         "prior": prior if prior is not None else "tetra3", **sol.to_json()})

    return cmd


def commands() -> list[click.Command]:
    """The attitude study's own commands: ``solve``."""
    return [solve_command()]
