"""The PSINS text ``.imu`` log ("SIMU log" of the PSINS toolbox), read as a `Run`.

Layout: ``%`` comment lines, then three header rows of six numbers, then one
row of six integer counts per sample::

    pitch0 roll0 yaw0 (deg)  VE0 VN0 VU0 (m/s)           -- initial state, approximate
    latitude (deg) longitude (deg) height (m) t0 (s) interval (ms) g (m/s^2)
    gf_x gf_y gf_z (arcsec/count)  af_x af_y af_z (ug*s/count)
    dtheta_x dtheta_y dtheta_z dv_x dv_y dv_z            -- counts, one row per sample

Counts become SI with the third row: ``dtheta = count * gf`` arcsec,
``dv = count * af * 1e-6 * g`` m/s, where g is the header's (PSINS's own
"ug" is 1e-6 of its g0, 9.780327). The axes are kept as stored (PSINS mounts
the unit X right, Y forward, Z up); the calibration needs no particular
body frame. Each row is the increment over the interval ending at
``t0 + (k + 1) * interval``.
"""

from __future__ import annotations

import math
import os

import numpy as np

from calib.errors import CalibError

from .checks import check_run
from .run import Run, make_meta

ARCSEC = math.pi / (180.0 * 3600.0)  # rad


def _numbers(line: str, count: int, where: str, what: str) -> list[float]:
    """One header row: exactly ``count`` finite numbers."""
    fields = line.split()
    try:
        values = [float(f) for f in fields]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise CalibError(
            f"header row '{line.strip()[:60]}' is not {count} numbers ({what})",
            where,
            "a PSINS .imu log has three header rows of six numbers before the samples (see docs/logs.md)",
        )
    return values


def _rows(path: str | os.PathLike) -> tuple[list[tuple[int, str]], str]:
    """Non-comment, non-blank lines with their 1-based numbers."""
    name = str(path)
    try:
        with open(path, "rb") as handle:
            text = handle.read().decode("utf-8", errors="strict")
    except FileNotFoundError:
        raise CalibError("file not found", name, "check the path") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibError(f"cannot read the file as text: {exc}", name, "give a PSINS text .imu log") from None
    lines = [
        (i + 1, ln)
        for i, ln in enumerate(text.splitlines())
        if ln.strip() and not ln.lstrip().startswith("%")
    ]
    return lines, name


def _counts(body: list[tuple[int, str]], name: str) -> np.ndarray:
    """The (n, 6) integer counts; a bad row is named by its line."""
    try:
        data = np.array([ln.split() for _, ln in body], dtype=np.float64)
    except ValueError:
        data = None
    if data is None or data.ndim != 2 or data.shape[1] != 6:
        for number, ln in body:
            fields = ln.split()
            ok = len(fields) == 6
            try:
                [float(f) for f in fields]
            except ValueError:
                ok = False
            if not ok:
                raise CalibError(
                    f"sample row '{ln.strip()[:60]}' is not six counts",
                    f"{name}, line {number}",
                    "each sample row holds dtheta_x..z dv_x..z as integer counts",
                )
        # The caller passes at least two rows, so one of them was refused above.
        assert data is not None
    bad = np.flatnonzero(~np.all(np.isfinite(data) & (data == np.rint(data)), axis=1))
    if bad.size:
        number, ln = body[int(bad[0])]
        raise CalibError(
            f"sample row '{ln.strip()[:60]}' holds a value that is not an integer count",
            f"{name}, line {number}",
            "PSINS logs store integer counts; scale them with the third header row",
        )
    return data


def read_psins(path: str | os.PathLike, allow_gaps: bool = False) -> Run:
    """Read a PSINS ``.imu`` log as a `Run` (SI increments, site metadata from the header).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.imu`` file.
    allow_gaps : bool
        Passed to the run checks (a PSINS log has no time column, so it has no gaps).

    Returns
    -------
    Run
        ``meta`` holds ``latitude_deg``, ``height_m``, ``sample_rate_hz`` and
        ``gravity_mps2`` from the second header row, and ``psins_*`` keys for
        the rest of the header.

    Raises
    ------
    CalibError
        Naming the file and line of a malformed header or sample row.
    """
    lines, name = _rows(path)
    if len(lines) < 5:
        raise CalibError(
            f"only {len(lines)} non-comment lines; a PSINS log has three header "
            "rows and at least two samples",
            name,
            "give a complete .imu log",
        )
    state = _numbers(lines[0][1], 6, f"{name}, line {lines[0][0]}", "pitch roll yaw VE VN VU")
    site = _numbers(
        lines[1][1], 6, f"{name}, line {lines[1][0]}", "latitude longitude height t0 interval_ms g"
    )
    scale = _numbers(
        lines[2][1], 6, f"{name}, line {lines[2][0]}", "gyro arcsec/count x3, accel ug*s/count x3"
    )
    lat, lon, height, t0, interval_ms, g = site
    if interval_ms <= 0.0 or g <= 0.0 or min(scale) <= 0.0:
        raise CalibError(
            f"sampling interval {interval_ms:g} ms, g {g:g} m/s^2 and the six count scales must be positive",
            f"{name}, line {lines[1][0]}",
            "check the second and third header rows",
        )
    counts = _counts(lines[3:], name)
    period = interval_ms * 1e-3
    meta = make_meta(
        lat,
        height,
        1.0 / period,
        gravity_mps2=g,
        source_format="psins-imu",
        psins_longitude_deg=repr(lon),
        psins_t0_s=repr(t0),
        psins_initial_att_deg=" ".join(repr(v) for v in state[:3]),
        psins_initial_vel_mps=" ".join(repr(v) for v in state[3:]),
        psins_scale=" ".join(repr(v) for v in scale),
    )
    run = Run(
        time_s=t0 + np.arange(1, len(counts) + 1) * period,
        dtheta_rad=counts[:, :3] * (np.asarray(scale[:3]) * ARCSEC),
        dv_mps=counts[:, 3:] * (np.asarray(scale[3:]) * 1e-6 * g),
        meta=meta,
        source=name,
    )
    check_run(run, allow_gaps)
    return run
