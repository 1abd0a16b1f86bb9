"""``simcam optics``: trace a lens prescription, print its table, write plots.

Registered on the ``simcam`` command group by :mod:`simcam.cli`.
"""

from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np

from simcam.infra.cli import overwrite_option
from simcam.starcam.lens.backend import get_backend
from simcam.starcam.lens.prescription import load_prescription
from simcam.starcam.lens.products import cache_dir, lens_products
from simcam.units import ARCSEC_PER_RAD

__all__ = ["format_table", "optics_command", "write_plots"]

DEFAULT_LENS = "embedded:star_camera"


def _fmt_row(cells, widths):
    return "  ".join(str(c).rjust(w) for c, w in zip(cells, widths))


def _table(headers, rows) -> str:
    cells = [headers] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    out = [_fmt_row(headers, widths), "  ".join("-" * w for w in widths)]
    out += [_fmt_row(r, widths) for r in cells[1:]]
    return "\n".join(out)


def format_table(products, prescription, fit) -> str:
    """The per-field table printed by ``simcam optics`` (px at the analysis pixel pitch)."""
    p_mm = products.pixel_pitch_um * 1e-3
    wl = products.wavelength_nm
    u = -products.centroid_x_mm / p_mm
    from scipy.interpolate import CubicSpline

    u_ref = CubicSpline(wl, u, axis=1)(products.reference_wavelength_nm)
    ideal = fit.efl_mm * np.tan(np.radians(products.field_deg)) / p_mm
    sig = np.sqrt(np.mean((products.sigma_x_mm**2 + products.sigma_y_mm**2) / 2.0, axis=1)) / p_mm
    rows = []
    for f in range(products.field_deg.size):
        rows.append([
            f"{products.field_deg[f]:.4f}", f"{ideal[f]:.3f}", f"{u_ref[f]:.4f}", f"{u_ref[f] - ideal[f]:+.4f}",
            f"{u[f, 0] - u_ref[f]:+.4f}", f"{u[f, -1] - u_ref[f]:+.4f}",
            f"{1e3 * products.rms_radius_mm[f].min():.2f}-{1e3 * products.rms_radius_mm[f].max():.2f}",
            f"{sig[f]:.3f}", f"{100 * products.transmitted_fraction[f].min():.1f}",
        ])
    headers = ["field_deg", "ideal_u_px", "u_ref_px", "distortion_px", f"colour_{wl[0]:g}nm_px",
               f"colour_{wl[-1]:g}nm_px", "rms_radius_um", "blur_sigma_px", "transmitted_%"]
    return _table(headers, rows)


def write_plots(products, fit, out: Path) -> list[Path]:
    """Spot diagrams, distortion map, lateral-colour curves and PSF stamps as PNG files in ``out``."""
    import matplotlib

    matplotlib.use("Agg")

    p_mm = products.pixel_pitch_um * 1e-3
    wl = products.wavelength_nm
    u = -products.centroid_x_mm / p_mm
    from scipy.interpolate import CubicSpline

    u_ref = CubicSpline(wl, u, axis=1)(products.reference_wavelength_nm)
    return [
        _plot_spots(products, u, u_ref, out / "spot_diagrams.png"),
        _plot_distortion(products, fit, u_ref, out / "distortion.png"),
        _plot_lateral_colour(products, u, u_ref, out / "lateral_colour.png"),
        _plot_psf(products, out / "psf.png"),
    ]


def _plot_spots(products, u, u_ref, path: Path) -> Path:
    """Spot diagrams: one panel per field, every wavelength, offset by its lateral colour."""
    import matplotlib.pyplot as plt

    wl = products.wavelength_nm
    nf = products.field_deg.size
    cmap = plt.get_cmap("turbo")
    colours = [cmap(i / max(1, wl.size - 1)) for i in range(wl.size)]
    picks = np.unique(np.linspace(0, nf - 1, min(nf, 5)).round().astype(int))
    fig, axes = plt.subplots(1, picks.size, figsize=(3.2 * picks.size, 3.6), squeeze=False)
    for ax, f in zip(axes[0], picks):
        for li in range(wl.size):
            off = -(u[f, li] - u_ref[f]) * products.pixel_pitch_um  # lens frame: x = -u p
            ax.plot(1e3 * products.spot_dx_mm[f, li] + off, 1e3 * products.spot_dy_mm[f, li], ".", ms=0.6,
                    color=colours[li], rasterized=True)
        ax.set_title(f"{products.field_deg[f]:.2f} deg", fontsize=9)
        ax.set_xlabel("x (um)")
        ax.set_aspect("equal")
        half = products.pixel_pitch_um / 2.0
        ax.add_patch(plt.Rectangle((-half, -half), 2 * half, 2 * half, fill=False, lw=0.8, color="k",
                                   label=f"1 px ({products.pixel_pitch_um:g} um)", zorder=3))
        # the whole box in view, whatever the spot size
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        ax.set_xlim(min(x0, -1.2 * half), max(x1, 1.2 * half))
        ax.set_ylim(min(y0, -1.2 * half), max(y1, 1.2 * half))
    axes[0][0].set_ylabel("y (um)")
    axes[0][0].legend(fontsize=7, loc="upper left")
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(wl[0], wl[-1]))
    fig.colorbar(sm, ax=list(axes[0]), shrink=0.8, pad=0.01).set_label("wavelength (nm)", fontsize=8)
    fig.suptitle(f"{products.prescription_name}: spot diagrams ({wl[0]:g}-{wl[-1]:g} nm, box = 1 px)", fontsize=10)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _plot_distortion(products, fit, u_ref, path: Path) -> Path:
    """Distortion: the radial curve with the simulator's fit, and a map over the field."""
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4))
    ideal = fit.ideal_u_px
    a1.plot(products.field_deg, u_ref - ideal, "o", label="traced centroid")
    ff = np.linspace(0, products.field_deg.max(), 200)
    u_ff = np.interp(ff, products.field_deg, ideal)  # ideal radius of each plotted field angle
    du, _ = fit.distortion().displacement(u_px=u_ff, v_px=np.zeros_like(ff))
    a1.plot(ff, du, "-", label="simulator fit (Brown-Conrady + cubic)")
    a1.set_xlabel("field (deg)")
    a1.set_ylabel(f"distortion at {products.reference_wavelength_nm:g} nm (px)")
    a1.legend(fontsize=8)
    a1.grid(alpha=0.3)
    r_max = ideal.max() / np.sqrt(2.0)
    g = np.linspace(-r_max, r_max, 13)
    gu, gv = np.meshgrid(g, g)
    r = np.hypot(gu, gv)
    dr = np.interp(r, ideal, u_ref - ideal)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux = np.where(r > 0, gu / r, 0.0)
        uy = np.where(r > 0, gv / r, 0.0)
    q = a2.quiver(gu, gv, dr * ux, dr * uy, dr, cmap="viridis", angles="xy")
    fig.colorbar(q, ax=a2, label="|distortion| (px)")
    a2.set_aspect("equal")
    a2.set_xlabel("u (px)")
    a2.set_ylabel("v (px)")
    a2.set_title("distortion map (arrows not to scale)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _plot_lateral_colour(products, u, u_ref, path: Path) -> Path:
    """Lateral colour: the radial centroid shift from the reference wavelength, per field."""
    import matplotlib.pyplot as plt

    wl = products.wavelength_nm
    nf = products.field_deg.size
    fig, ax = plt.subplots(figsize=(6.5, 4.4))
    fcm = plt.get_cmap("viridis")
    for f in range(1, nf):
        ax.plot(wl, u[f] - u_ref[f], "o-", ms=3, color=fcm(f / max(1, nf - 1)),
                label=f"{products.field_deg[f]:.2f} deg")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel(f"radial centroid shift from {products.reference_wavelength_nm:g} nm (px)")
    ax.set_title(f"{products.prescription_name}: lateral colour", fontsize=10)
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def _plot_psf(products, path: Path) -> Path:
    """PSF stamps (log scale) at the edge and centre of the field, three wavelengths."""
    import matplotlib.pyplot as plt

    wl = products.wavelength_nm
    nf = products.field_deg.size
    lpick = np.unique(np.linspace(0, wl.size - 1, 3).round().astype(int))
    fpick = np.unique([0, nf // 2, nf - 1])
    fig, axes = plt.subplots(fpick.size, lpick.size, figsize=(3 * lpick.size, 3 * fpick.size), squeeze=False)
    L = products.psf.shape[-1]
    c = L // 2
    h = min(c, 8)
    for i, f in enumerate(fpick):
        for j, li in enumerate(lpick):
            img = products.psf[f, li, c - h:c + h + 1, c - h:c + h + 1]
            axes[i][j].imshow(np.log10(np.clip(img, 1e-6, None)), origin="lower", vmin=-6, vmax=0,
                              extent=(-h - 0.5, h + 0.5, -h - 0.5, h + 0.5))
            axes[i][j].set_title(f"{products.field_deg[f]:.2f} deg, {wl[li]:g} nm", fontsize=8)
    fig.suptitle("pixel-integrated PSF (log10 of the flux fraction per px)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


@click.command("optics")
@click.argument("prescription", required=False, default=DEFAULT_LENS)
@click.option("--out", "out", type=click.Path(file_okay=False), default=None,
              help="Directory for the plots, products.nc and table.csv (default: print only).")
@overwrite_option
@click.option("--no-cache", "no_cache", is_flag=True, help="Trace again even if the products are cached.")
@click.option("--variant", type=click.Choice(["llvm_ad_rgb", "scalar_rgb"]), default=None,
              help="Mitsuba variant (default: llvm_ad_rgb if available).")
def optics_command(prescription, out, overwrite, no_cache, variant) -> None:
    """Trace the lens PRESCRIPTION (TOML file or embedded:NAME, default embedded:star_camera):
    paraxial data, distortion, lateral colour, spots and PSFs, and their fit to the
    simulator's optics models."""
    from simcam.starcam.lens.simulator import simulator_optics

    t0 = time.perf_counter()
    presc = load_prescription(prescription)
    an = presc.analysis
    backend = get_backend(variant)
    state = {"last": 0.0}

    def progress(done, total):
        now = time.perf_counter()
        if now - state["last"] > 1.0 or done == total:
            state["last"] = now
            click.echo(f"\rtracing {done}/{total} bundles", nl=done == total, err=True)

    prod = lens_products(presc, use_cache=not no_cache, variant=variant, progress=progress)
    fit = simulator_optics(
        prod, presc, pixel_pitch_um=an.pixel_pitch_um, focal_length_mm=prod.efl_mm, r_norm_px=2048.0,
        ref_wavelength_nm=an.reference_wavelength_nm, wavelength_min_nm=an.wavelength_min_nm,
        wavelength_max_nm=an.wavelength_max_nm,
    )
    scale = an.pixel_pitch_um * 1e-3 / prod.efl_mm * ARCSEC_PER_RAD
    click.echo(f"lens       {presc.name} (hash {presc.hash}): {len(presc.surfaces)} surfaces; {presc.description}")
    click.echo(f"tracer     Mitsuba {backend.variant}; {backend.note}")
    src = f"cache {cache_dir()}" if prod.from_cache else f"traced in {prod.elapsed_s:.2f} s"
    click.echo(f"products   {an.field_points} fields x {an.wavelength_points} wavelengths x "
               f"{prod.rays_per_bundle} rays ({src})")
    click.echo(f"paraxial   f' {prod.efl_mm:.6f} mm, BFD {prod.bfd_mm:.6f} mm, f/{prod.f_number:.4f}, "
               f"entrance pupil {2 * prod.entrance_pupil_radius_mm:.4f} mm at z = {prod.entrance_pupil_z_mm:.4f} mm "
               f"(at {an.reference_wavelength_nm:g} nm); {scale:.6f} arcsec/px at {an.pixel_pitch_um:g} um")
    click.echo(f"focus      {prod.focus}: image plane {prod.back_focal_distance_mm:.6f} mm behind the last vertex "
               f"({prod.back_focal_distance_mm - prod.bfd_mm:+.6f} mm from the paraxial focus)")
    click.echo("")
    click.echo(format_table(prod, presc, fit))
    click.echo("")
    click.echo(f"simulator  (r_norm 2048 px, reference {fit.ref_wavelength_nm:g} nm) psf airy, sigma0 "
               f"{fit.sigma0_px:.4f} px, sigma_r2 {fit.sigma_r2_px:.4f} px (fit rms {fit.psf_sigma_rms_px:.4f} px)")
    click.echo(f"           distortion k1 {fit.k1:.6e}, k2 {fit.k2:.6e}, scale {fit.cubic_x_px[1] / 2048.0:+.3e} "
               f"(fit residual rms {fit.distortion_rms_px:.2e} px, max {fit.distortion_max_px:.2e} px)")
    table = fit.radial_px_per_nm
    click.echo(f"           lateral colour {len(table)} x {len(table[0])} table radial_px_per_nm (powers of "
               f"wavelength x field^2) (fit residual rms {fit.lateral_colour_rms_px:.2e} px, max "
               f"{fit.lateral_colour_max_px:.2e} px)")
    if out is not None:
        import pandas as pd

        from simcam import io

        lens_file = () if str(prescription).startswith("embedded:") else (prescription,)
        with io.atomic_directory(out, overwrite=overwrite, inputs=lens_file) as tmp:
            prod.save(tmp / "products.nc")
            rows = []
            p_mm = an.pixel_pitch_um * 1e-3
            for f, fd in enumerate(prod.field_deg):
                for li, w in enumerate(prod.wavelength_nm):
                    rows.append({"field_deg": fd, "wavelength_nm": w, "centroid_x_mm": prod.centroid_x_mm[f, li],
                                 "centroid_y_mm": prod.centroid_y_mm[f, li], "chief_x_mm": prod.chief_x_mm[f, li],
                                 "u_px": -prod.centroid_x_mm[f, li] / p_mm,
                                 "sigma_x_um": 1e3 * prod.sigma_x_mm[f, li], "sigma_y_um": 1e3 * prod.sigma_y_mm[f, li],
                                 "transmitted_fraction": prod.transmitted_fraction[f, li]})
            pd.DataFrame(rows).to_csv(tmp / "table.csv", index=False, float_format="%.10g")
            files = write_plots(prod, fit, tmp)
        click.echo(f"wrote      {Path(out)}: products.nc, table.csv, " + ", ".join(f.name for f in files))
    click.echo(f"time       {time.perf_counter() - t0:.2f} s")
