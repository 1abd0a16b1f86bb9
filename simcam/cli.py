"""`simcam` command line: the world (scenarios, rendering)."""

from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np
import pandas as pd

from simcam import __version__
from simcam.infra.cli import overwrite_option, run_cli
from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import progress as progress_bar
from simcam.starcam.scenario import load, scenario_source_text, scenario_to_toml
from simcam.starcam.targets import star_grid


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="simcam")
def cli() -> None:
    """Physics-based star-camera simulator: scenarios in, FITS frames and truth out."""


@cli.command("scenario")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--resolved", is_flag=True, help="Every field, defaults filled in (no comments).")
def scenario_command(scenario: str | None, resolved: bool) -> None:
    """Print SCENARIO (default: the embedded seed-000 one) as TOML with its comments;
    --resolved: every field, defaults filled in."""
    scn = load(scenario)
    click.echo(f"# scenario hash {scn.hash}, simcam {__version__}")
    text = None if resolved else scenario_source_text(scenario)
    click.echo(scenario_to_toml(scn) if text is None else text, nl=False)


@cli.command("render")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--frames", "n_frames", type=click.IntRange(min=1), default=1, show_default=True,
              help="Number of frames.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Run seed (temporal noise); the scenario seed fixes PRNU/DSNU and targets.")
@click.option("--mode", type=click.Choice(["full", "windows"]), default="full", show_default=True,
              help="full: mosaic frames; windows: stamps around each star (same pixels).")
@click.option("--filter", "filter_nm", type=float, default=None,
              help="Centre wavelength (nm) of a lab filter in front of the target (default: none).")
@click.option("--out", "out", required=True, type=click.Path(file_okay=False), help="Output directory.")
@overwrite_option
@click.option("--compress", is_flag=True,
              help="Full frames as Rice tile-compressed FITS (lossless; `budget starcam measure` reads them).")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bar on stderr (only on a terminal).")
def render_command(scenario, n_frames, seed, mode, filter_nm, out, overwrite, compress, progress) -> None:
    """Render the star target of SCENARIO (default: embedded seed-000) to FITS + truth.csv."""
    from simcam import io
    from simcam.starcam.render import Placement, StarCamera

    t0 = time.perf_counter()
    if compress and mode != "full":
        raise UserInputError("--compress: only full frames are compressed (--mode full)")
    scn = load(scenario)
    if filter_nm is not None and filter_nm not in [f.center_nm for f in scn.lab.filters]:
        raise UserInputError(
            f"--filter {filter_nm:g}: no lab filter centred there (lab.filters: "
            f"{', '.join(f'{f.center_nm:g}' for f in scn.lab.filters)})"
        )
    if mode == "full":  # before the camera allocates any full-frame map
        io.check_render_request(scn, frames=n_frames, out=out, source=str(scenario or "<embedded scenario>"),
                                echo=lambda _msg: None)
    cam = StarCamera(scn)
    placement = Placement(layout=star_grid(scn), filter_nm=filter_nm, condition=0, label="target")
    scene = cam.scene(placement)
    io.check_render_request(scn, frames=n_frames, out=out, source=str(scenario or "<embedded scenario>"), mode=mode,
                            n_stars=len(scene.truth), compress=compress and mode == "full")
    truth_rows = []
    manifest = []
    hdr_kw = dict(scenario=scn, seed=seed, condition=0, filter_nm=filter_nm,
                  platform_dx_px=0.0, platform_dy_px=0.0, label="target")
    peak_dn = []
    with io.atomic_directory(out, overwrite=overwrite, inputs=(scenario,)) as tmp:
        if mode == "full":
            expected = cam.expected_frame_e(scene)
            bar = progress_bar(total=n_frames, desc="frames", unit="frame", enabled=progress)
            for f in range(n_frames):
                frame = cam.render_frame(scene, frame=f, seed=seed, expected_e=expected)
                name = f"frame_{f:04d}.fits"
                io.write_frame(tmp / name, frame, io.frame_header(frame=f, **hdr_kw), compress=compress)
                bar.update(1)
                manifest.append({"file": name, "frame": f, "condition": 0,
                                 "filter_nm": filter_nm, "field": "target"})
                peak_dn.append(float(frame.max()))
            bar.close()
        else:
            win = cam.render_windows(scene, frames=n_frames, seed=seed)
            io.write_windows(tmp / "windows.fits", win.pixels, win.col0, win.row0,
                             io.frame_header(frame=0, **hdr_kw))
            for f in range(n_frames):
                manifest.append({"file": "windows.fits", "frame": f, "condition": 0,
                                 "filter_nm": filter_nm, "field": "target"})
            peak_dn.append(float(win.pixels.max()))
        for f in range(n_frames):
            t = scene.truth.copy()
            t.insert(1, "frame", f)
            truth_rows.append(t)
        pd.concat(truth_rows, ignore_index=True).to_csv(tmp / "truth.csv", index=False, float_format="%.10g")
        pd.DataFrame(manifest).to_csv(tmp / "manifest.csv", index=False)
        (tmp / "scenario.toml").write_text(scenario_to_toml(scn))
    dt = time.perf_counter() - t0
    tr = scene.truth
    click.echo(f"scenario   {scn.name} (hash {scn.hash})")
    click.echo(f"rendered   {n_frames} {mode} frame(s) of {len(tr)} stars, seed {seed}, "
               f"filter {'none' if filter_nm is None else f'{filter_nm:g} nm'} -> {Path(out)}")
    click.echo(f"signal     {tr['electrons'].iloc[0]:.0f} e- per star per exposure; "
               f"background {scene.background_e:.2f} e-/px; peak {max(peak_dn):.0f} DN")
    click.echo(f"positions  x {tr['x_true'].min():.2f}..{tr['x_true'].max():.2f}, "
               f"y {tr['y_true'].min():.2f}..{tr['y_true'].max():.2f} (mosaic px, 0-based)")
    d_rms = float(np.sqrt(np.mean(tr["distortion_dx_px"] ** 2 + tr["distortion_dy_px"] ** 2)))
    click.echo(f"injected   distortion {d_rms:.4f} px rms; chromatic (spectrum-weighted) "
               f"({tr['chromatic_dx_px'].mean():+.4f}, {tr['chromatic_dy_px'].mean():+.4f}) px mean")
    click.echo(f"time       {dt:.2f} s")


def _register_lens_commands() -> None:
    from simcam.starcam.lens.cli import optics_command

    cli.add_command(optics_command)


_register_lens_commands()


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    run_cli(cli, argv)
