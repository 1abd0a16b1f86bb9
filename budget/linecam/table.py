"""The observation table of the line camera: one row per identified star crossing the line.

``budget linecam calibrate`` reads it (:func:`read_observations`), so that a real camera
can be calibrated; ``budget linecam simulate --csv`` writes it (:func:`write_observation_csv`).
CSV, one row per identified star crossing the line, header required, extra columns ignored:

==============  ==================================================================
column          meaning
==============  ==================================================================
time_s          time tag of the centroid (mid-exposure), s after ``--epoch``
sample_px       centroid along the line, px (pixel centres at 0 .. n_pixels - 1)
hip             Hipparcos catalogue number of the star
q_w q_x q_y q_z reported attitude, body (nominal camera) -> GCRS, unit quaternion,
                scalar first
pos_x_km ...    spacecraft geocentric position ``pos_x_km, pos_y_km, pos_z_km`` (GCRS)
vel_x_km_s ...  spacecraft geocentric velocity ``vel_x_km_s, vel_y_km_s, vel_z_km_s``
pass            optional: pass number (reports only)
==============  ==================================================================

The camera's nominal model (focal length, pitch, number of detectors, line position) and
the lab's settings come from ``--scenario`` (default: the embedded scenario). ``simulate``
writes exactly this table for a simulated calibration (``--csv``), so the two commands
round-trip.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from simcam.infra.errors import UserInputError
from simcam.infra.outputs import check_input_file
from simcam.sky.apparent import aberration_first_order, apparent_directions
from simcam.sky.catalogue import CatalogueError, hipparcos
from simcam.units import SECONDS_PER_DAY

if TYPE_CHECKING:
    from .model import Observations

__all__ = ["CSV_COLUMNS", "ObservationTable", "read_observations", "parse_epoch", "check_observation_values",
           "write_observation_csv"]

CSV_COLUMNS = ("time_s", "sample_px", "hip", "q_w", "q_x", "q_y", "q_z", "pos_x_km", "pos_y_km", "pos_z_km",
               "vel_x_km_s", "vel_y_km_s", "vel_z_km_s")


@dataclass(frozen=True)
class ObservationTable:
    """An observation table as read (:func:`read_observations`).

    Attributes
    ----------
    source : str
        The file's name as given (errors and outputs name it).
    observations : budget.linecam.model.Observations
        The stars' apparent directions in the reported body frame, their samples, passes
        and catalogue numbers.
    t_s : numpy.ndarray
        Their time tags (s after the epoch).
    """

    source: str
    observations: Observations
    t_s: np.ndarray


def parse_epoch(epoch_utc: str, *, field: str):
    """The UTC epoch ``epoch_utc`` (ISO) as an :class:`astropy.time.Time`; anything else is a
    :class:`simcam.infra.errors.UserInputError` naming ``field``."""
    from astropy.time import Time

    try:
        return Time(epoch_utc, scale="utc")
    except ValueError:
        raise UserInputError(f"{field}: not an ISO UTC time: {epoch_utc!r}") from None


def read_observations(path, scn, *, epoch=None) -> ObservationTable:
    """Read and check an observation table: the stars' apparent directions in the reported
    body frame (:class:`budget.linecam.model.Observations`) and their time tags.

    ``epoch``: the UTC epoch of ``time_s``, an ISO string or an :class:`astropy.time.Time`
    (:func:`parse_epoch`); None is the scenario's ``orbit.epoch_utc``. Every problem is a
    :class:`simcam.infra.errors.UserInputError` naming the file and field.
    """
    import pandas as pd
    from astropy.time import Time
    from scipy.spatial.transform import Rotation

    from .model import Observations

    src = str(path)
    p = check_input_file(path, what="observation table")  # a FIFO or a device is not read
    try:
        # only an empty cell is missing: a literal "nan" or "NA" is kept as written, and named so
        df = pd.read_csv(p, encoding="utf-8-sig", keep_default_na=False, na_values=[""])
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise UserInputError(f"{src}: not a readable CSV table ({str(exc).splitlines()[0]})") from None
    missing = [c for c in CSV_COLUMNS if c not in df.columns]
    if missing:
        raise UserInputError(f"{src}: {missing[0]}: missing column (needed: {', '.join(CSV_COLUMNS)})")
    if len(df) == 0:
        raise UserInputError(f"{src}: rows: the table has no observations")
    arr = {}
    for c in CSV_COLUMNS:
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raw = df[c].iloc[bad[0]]
            got = "an empty cell" if pd.isna(raw) else repr(str(raw))
            raise UserInputError(f"{src}: {c}: not a finite number in row {int(bad[0]) + 2} (got {got})")
        arr[c] = v
    check_observation_values(src, arr, n_pixels=scn.camera.n_pixels)
    hip = arr["hip"]
    if np.any(hip != np.round(hip)) or np.any(hip < 1):
        r = int(np.flatnonzero((hip != np.round(hip)) | (hip < 1))[0])
        raise UserInputError(f"{src}: hip: not a catalogue number in row {r + 2} (got {df['hip'].iloc[r]!r})")
    n_pix = scn.camera.n_pixels
    s = arr["sample_px"]
    out = np.flatnonzero((s < -0.5) | (s > n_pix - 0.5))
    if out.size:
        raise UserInputError(f"{src}: sample_px: {s[out[0]]:g} in row {int(out[0]) + 2} is off the line "
                             f"(0 .. {n_pix - 1} for camera.n_pixels = {n_pix})")
    q = np.column_stack([arr["q_x"], arr["q_y"], arr["q_z"], arr["q_w"]])
    qn = np.linalg.norm(q, axis=1)
    out = np.flatnonzero(np.abs(qn - 1.0) > 1e-6)
    if out.size:
        raise UserInputError(f"{src}: q_w: the quaternion in row {int(out[0]) + 2} is not a unit quaternion "
                             f"(norm {qn[out[0]]:.9g})")
    try:
        cat = hipparcos().by_hip(hip.astype(np.int64))
    except CatalogueError as exc:
        raise UserInputError(f"{src}: hip: {exc}") from None
    t = arr["time_s"]
    pos = np.column_stack([arr["pos_x_km"], arr["pos_y_km"], arr["pos_z_km"]])
    vel = np.column_stack([arr["vel_x_km_s"], arr["vel_y_km_s"], arr["vel_z_km_s"]])
    if epoch is None:
        epoch = Time(scn.orbit.epoch_utc, scale="utc")
    elif not isinstance(epoch, Time):
        epoch = parse_epoch(epoch, field="epoch")
    import astropy.units as u

    lab = scn.lab
    ref = int(np.argsort(t)[t.size // 2])
    a = apparent_directions(cat, epoch + t[ref] * u.s, observer_position_km=pos[ref], observer_velocity_km_s=vel[ref],
                            proper_motion=lab.proper_motion, parallax=lab.parallax, aberration=lab.aberration)
    if lab.aberration:  # first-order differential aberration for each row's velocity (|v||dv|/c^2 < 2e-9 rad)
        a = aberration_first_order(a, vel - vel[ref])
    att = Rotation.from_quat(q / qn[:, None]).as_matrix()
    b = np.einsum("nji,nj->ni", att, a)
    passes = pd.to_numeric(df["pass"], errors="coerce").fillna(0).to_numpy(dtype=int) if "pass" in df else \
        np.zeros(len(df), dtype=int)
    return ObservationTable(source=src, observations=Observations(b=b, sample=s, pass_index=passes,
                                                                  hip=hip.astype(np.int64)), t_s=t)


#: a physical observation table: times within a century of the epoch, the
#: spacecraft between the Earth's surface and ten times the Moon's distance, at less than
#: the Earth's escape speed from its surface (11.2 km/s) plus margin
MAX_ABS_TIME_S = 100 * 365.25 * SECONDS_PER_DAY
MIN_RADIUS_KM, MAX_RADIUS_KM = 6356.0, 4.0e6
MAX_SPEED_KM_S = 20.0
#: at least this many distinct catalogue stars (each gives two equations; ten parameters)
MIN_DISTINCT_STARS = 6
#: the samples must spread over at least this many pixels along the line
MIN_SAMPLE_SPREAD_PX = 2.0


def check_observation_values(src: str, arr: dict, *, n_pixels: int) -> None:
    """What makes a calibration from this table meaningless, refused with the file and field:
    duplicated rows (counted twice, they overstate the stated precision by sqrt 2),
    non-physical times, positions and velocities, too few distinct stars, all samples at
    one pixel. ``arr``: the table's columns as float arrays (already finite)."""
    t = arr["time_s"]
    bad = np.flatnonzero(np.abs(t) > MAX_ABS_TIME_S)
    if bad.size:
        raise UserInputError(f"{src}: time_s: {t[bad[0]]:g} s in row {int(bad[0]) + 2} is more than a century "
                             f"from the epoch (|time_s| <= {MAX_ABS_TIME_S:.3g})")
    r = np.sqrt(arr["pos_x_km"] ** 2 + arr["pos_y_km"] ** 2 + arr["pos_z_km"] ** 2)
    bad = np.flatnonzero((r < MIN_RADIUS_KM) | (r > MAX_RADIUS_KM))
    if bad.size:
        raise UserInputError(f"{src}: pos_x_km: the position in row {int(bad[0]) + 2} is {r[bad[0]]:.6g} km from "
                             f"the Earth's centre (an orbit is between {MIN_RADIUS_KM:g} and {MAX_RADIUS_KM:g} km)")
    v = np.sqrt(arr["vel_x_km_s"] ** 2 + arr["vel_y_km_s"] ** 2 + arr["vel_z_km_s"] ** 2)
    bad = np.flatnonzero(v > MAX_SPEED_KM_S)
    if bad.size:
        raise UserInputError(f"{src}: vel_x_km_s: the speed in row {int(bad[0]) + 2} is {v[bad[0]]:.6g} km/s "
                             f"(an orbit is slower than {MAX_SPEED_KM_S:g} km/s)")
    table = np.column_stack([arr[c] for c in CSV_COLUMNS])
    _, first, inverse, counts = np.unique(table, axis=0, return_index=True, return_inverse=True,
                                          return_counts=True)
    if np.any(counts > 1):
        inverse = np.ravel(inverse)
        dup = int(np.flatnonzero(first[inverse] != np.arange(inverse.size))[0])  # the first later copy
        k = int(inverse[dup])
        raise UserInputError(f"{src}: rows: row {dup + 2} repeats row {int(first[k]) + 2} "
                             f"({int((counts - 1).clip(0).sum())} duplicated row(s)); a repeated observation "
                             "is counted twice and overstates the stated precision: remove the duplicates")
    stars = np.unique(arr["hip"]).size
    if stars < MIN_DISTINCT_STARS:
        raise UserInputError(f"{src}: rows: {stars} distinct star(s) (column hip); a calibration needs at "
                             f"least {MIN_DISTINCT_STARS}: too few stars")
    s = arr["sample_px"]
    if float(np.ptp(s)) < MIN_SAMPLE_SPREAD_PX:
        raise UserInputError(f"{src}: sample_px: every observation is at pixel {np.median(s):.6g} (spread "
                             f"{float(np.ptp(s)):.3g} px of the {n_pixels}); the field along the line is not "
                             "determined")


def write_observation_csv(scn, sim, path) -> None:
    """The identified observations of a simulation as the table ``calibrate`` reads."""
    import pandas as pd
    from scipy.spatial.transform import Rotation

    from simcam.linecam.attitude import orbit_state

    idf = sim.identified
    q = Rotation.from_matrix(idf.attitude).as_quat()  # scalar last
    pos, vel = orbit_state(scn, idf.t_s)
    df = pd.DataFrame({"time_s": idf.t_s, "sample_px": idf.obs.sample, "hip": idf.obs.hip,
                       "q_w": q[:, 3], "q_x": q[:, 0], "q_y": q[:, 1], "q_z": q[:, 2],
                       "pos_x_km": pos[:, 0], "pos_y_km": pos[:, 1], "pos_z_km": pos[:, 2],
                       "vel_x_km_s": vel[:, 0], "vel_y_km_s": vel[:, 1], "vel_z_km_s": vel[:, 2],
                       "pass": idf.obs.pass_index})
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(path, index=False, float_format="%.17g")
