"""`budget starcam simulate PROTOCOL`: a lab dry run, written as the lab's own data would be.

Renders every condition of a protocol's acquisition plan as full FITS frames, with a
``manifest.csv`` in the format ``budget starcam measure`` reads, the grid target's
``reference.csv`` (distortion), and ``truth.csv`` (what was injected), so that
``budget starcam measure PROTOCOL DIR`` can be tried on data whose answer is known.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click
import numpy as np
import pandas as pd

import simcam
from budget.starcam.protocols import PROTOCOL_STREAM, PROTOCOLS, make_plan, reference_table
from simcam.infra.cli import overwrite_option, write_json_atomic
from simcam.infra.lifecycle import progress as progress_bar
from simcam.infra.outputs import check_run_outputs
from simcam.starcam.scenario import load, scenario_to_toml
from simcam.starcam.targets import calibration_grid, star_grid


def write_protocol_frames(protocol: str, scenario, *, seed: int, out: str | Path, dark_frames: int = 0,
                          frames: int | None = None, overwrite: bool = False, compress: bool = False,
                          progress: bool = False, source: str = "<embedded scenario>", inputs=()) -> pd.DataFrame:
    """Render the plan of ``protocol`` to FITS frames in ``out``; return the manifest.

    The request is checked against the memory and the free disk before any work, and a
    large output is announced on stderr (:func:`simcam.io.check_render_request`);
    ``compress`` writes Rice tile-compressed frames (lossless); ``out`` never holds one of
    ``inputs`` (the scenario file).
    """
    from simcam import io
    from simcam.starcam.render import Placement, StarCamera

    plan = make_plan(protocol, scenario, seed=seed, dark_frames=dark_frames)
    if frames is not None:
        plan = replace(plan, conditions=tuple(replace(c, frames=frames) for c in plan.conditions))
    n_files = sum(c.frames + plan.dark_frames for c in plan.conditions)
    io.check_render_request(scenario, frames=n_files, out=out, source=source, compress=compress)
    cam = StarCamera(scenario)
    rows, truths = [], []
    bar = progress_bar(total=n_files, desc=f"{protocol} frames", unit="frame", enabled=progress)
    # the world's hexapod pose errors and target drift (simcam.starcam.world): in the
    # frames, not in the plan or the headers (which hold what the lab commanded)
    motion = cam.world_motion(seed)
    with io.atomic_directory(out, overwrite=overwrite, inputs=inputs) as tmp:
        for c in plan.conditions:
            lay = calibration_grid(scenario) if c.target == "calibration_grid" else star_grid(scenario, center_px=c.field_center_px)
            stream = 1000 * PROTOCOL_STREAM[protocol] + c.index
            pdx, pdy, roll = (0.0, 0.0, 0.0) if motion is None else motion.pose(protocol, c.index)
            placement = Placement(layout=lay, platform_dx_px=c.platform_dx_px + pdx, platform_dy_px=c.platform_dy_px + pdy,
                                  filter_nm=c.filter_nm, condition=stream, label=c.label, platform_roll_rad=roll)
            if motion is None:
                placement = replace(placement, platform_dx_px=c.platform_dx_px, platform_dy_px=c.platform_dy_px)
            scene = cam.scene(placement)
            expected = cam.expected_frame_e(scene)
            drift = None if motion is None else motion.drift_of(protocol, c.index, c.frames)
            if drift is not None:
                # first order in the (sub-0.01 px) drift, as the Monte Carlo's windows
                # (StarCamera.drift_chain): the frame's expected charge and its gradient
                h = 1e-3
                grad = [(cam.expected_frame_e(cam.scene(replace(placement, platform_dx_px=placement.platform_dx_px + dx,
                                                                platform_dy_px=placement.platform_dy_px + dy)))
                         - cam.expected_frame_e(cam.scene(replace(placement,
                                                                  platform_dx_px=placement.platform_dx_px - dx,
                                                                  platform_dy_px=placement.platform_dy_px - dy))))
                        / (2 * h) for dx, dy in ((h, 0.0), (0.0, h))]
            kw = dict(scenario=scenario, seed=seed, condition=c.index, filter_nm=c.filter_nm,
                      platform_dx_px=c.platform_dx_px, platform_dy_px=c.platform_dy_px, label=c.field or c.label)
            for dark, count, tag in ((0, c.frames, "f"), (1, plan.dark_frames, "dark")):
                for f in range(count):
                    name = f"c{c.index:03d}_{tag}{f:04d}.fits"
                    exp_f = expected
                    if drift is not None and not dark:
                        exp_f = np.maximum(expected + drift[f, 0] * grad[0] + drift[f, 1] * grad[1], 0.0)
                    data = cam.render_frame(scene, frame=f, seed=seed, expected_e=exp_f, dark=bool(dark))
                    io.write_frame(tmp / name, data, io.frame_header(frame=f, **kw), compress=compress)
                    bar.update(1)
                    rows.append({"file": name, "condition": c.index, "frame": f, "filter_nm": c.filter_nm,
                                 "field": c.field or None, "dark": dark})
            t = scene.truth.copy()
            t["condition"] = c.index
            t["field"] = c.field
            truths.append(t)
        manifest = pd.DataFrame(rows)
        if protocol != "chromatic":
            manifest = manifest.drop(columns=["filter_nm", "field"])
        manifest.to_csv(tmp / "manifest.csv", index=False)
        pd.concat(truths, ignore_index=True).to_csv(tmp / "truth.csv", index=False, float_format="%.10g")
        if protocol == "distortion":
            reference_table(scenario, cam).to_csv(tmp / "reference.csv", index=False, float_format="%.10g")
        (tmp / "scenario.toml").write_text(scenario_to_toml(scenario))
    bar.close()
    return manifest


@click.command("simulate")
@click.argument("protocol", type=click.Choice(list(PROTOCOLS)))
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--frames", type=click.IntRange(min=2), default=None,
              help="Frames per condition (default: the scenario's protocol plan).")
@click.option("--dark-frames", type=click.IntRange(min=0), default=0, show_default=True,
              help="Star-free frames per condition for dark subtraction.")
@click.option("--out", required=True, type=click.Path(file_okay=False))
@overwrite_option
@click.option("--json", "json_out", type=click.Path(dir_okay=False),
              help="Write a summary (files, conditions, scenario hash, seed) as JSON.")
@click.option("--compress", is_flag=True,
              help="Rice tile-compressed FITS frames (lossless; `budget starcam measure` reads them).")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bar on stderr (only on a terminal).")
def simulate_command(protocol, scenario, seed, frames, dark_frames, out, overwrite, json_out, compress,
                     progress) -> None:
    """Write a simulated lab dataset of PROTOCOL (FITS + manifest) for `budget starcam measure`."""
    check_run_outputs(json_out=json_out, inputs=(scenario,))  # before the frames: never over the scenario
    scn = load(scenario)
    m = write_protocol_frames(protocol, scn, seed=seed, out=out, dark_frames=dark_frames, frames=frames,
                              overwrite=overwrite, compress=compress, progress=progress,
                              source=str(scenario or "<embedded scenario>"), inputs=(scenario,))
    if json_out:
        write_json_atomic(json_out, {
            "protocol": protocol, "out": str(out), "frames": int(len(m)),
            "conditions": int(m["condition"].nunique()), "dark_frames": int((m["dark"] == 1).sum()),
            "scenario_hash": scn.hash, "seed": seed, "version": simcam.__version__,
        })
    click.echo(f"{protocol}: wrote {len(m)} frames ({m['condition'].nunique()} condition(s)) to {out}; "
               f"try: budget starcam measure {protocol} {out}" + (f" --reference {out}/reference.csv" if protocol == "distortion" else ""))
