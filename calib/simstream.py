"""Simulate a long run straight to disk, a time window at a time.

:func:`calib.sim.simulate` holds the whole run in memory: a 2-hour run at
2 kHz (14.4 M samples) would need several GB before it is written.
:func:`simulate_to_file` calls the same exact per-sample kernel
(:func:`calib.sim.true_increments` on the sample ends of one window) window
by window, applies the 21 errors and the white noise, and appends the
samples to an NPZ (uncompressed, members written as they come) or a CSV
(``imu-run/1``) file; the memory it needs is one window's.

Without noise the samples are those of :func:`calib.sim.simulate` to the
last bit of the kinematics (the same closed-form integrals; the windows
only change where a sample's integral starts, not its value). With noise
the draws come window by window, so a seed gives a different (equally
distributed) noise sequence than :func:`calib.sim.simulate`. Not streamed
(refused with a clear message): Gauss-Markov bias instability, the optional
terms of :mod:`calib.extras`, flip errors and the gimbal encoder columns.
"""

from __future__ import annotations

import math
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from .errormodel import ErrorModel
from .errors import CalibError
from .fileio import atomic_write_with
from .profiles import NoiseProfile
from .sequence import Sequence, timeline
from .sim import SimConfig, Truth, true_increments
from .transform import rotvec_to_dcm

WINDOW_SAMPLES = 1 << 18  # 2 MB per column: I/O in large blocks, memory still small
FORMAT = "imu-run/1"


def run_meta(seq: Sequence, cfg: SimConfig) -> dict[str, str]:
    """The metadata :func:`calib.sim.simulate` writes, for the same site and sequence."""
    meta = {
        "format": FORMAT,
        "latitude_deg": repr(math.degrees(cfg.latitude_rad)),
        "height_m": repr(cfg.height_m),
        "sample_rate_hz": repr(cfg.sample_rate_hz),
    }
    if cfg.gravity_mps2 is not None:
        meta["gravity_mps2"] = repr(cfg.gravity_mps2)
    meta["sequence"] = seq.name
    return meta


def sample_windows(
    seq: Sequence,
    cfg: SimConfig,
    errors: ErrorModel,
    profile: NoiseProfile,
    setup_rotvec=(0.0, 0.0, 0.0),
    noise: bool = True,
    seed: int | None = None,
    window: int = WINDOW_SAMPLES,
):
    """Yield ``(time_s, dtheta_m, dv_m)`` of consecutive windows of the run (IMU output)."""
    if profile.has_gauss_markov and noise:
        raise CalibError(
            f"profile {profile.name!r} has Gauss-Markov bias instability, which the "
            "streamed simulator does not draw",
            "--profile",
            "use a white-noise profile, or `seqdesign simulate` for this run",
        )
    rng = np.random.default_rng(seed)
    tl = timeline(seq)
    R = rotvec_to_dcm(np.asarray(setup_rotvec, dtype=float))
    rate = cfg.sample_rate_hz
    n = int(math.floor(tl.duration_s * rate + 1e-9))  # as calib.sim.uniform_times
    for a in range(0, n, window):
        b = min(n, a + window)
        # The window's sample ends, and the end before it (0: the run's start) where its
        # first integral starts; the kernel integrates from 0 to ends[0] first: dropped.
        ends = np.arange(a, b + 1) / rate
        time_s, dtheta, dv = true_increments(tl, R, cfg, time_s=ends if a else ends[1:])
        if a:
            time_s, dtheta, dv = time_s[1:], dtheta[1:], dv[1:]
        dt = np.diff(ends)
        dtheta_m, dv_m = errors.apply(dtheta, dv, dt)
        if noise:
            sq = np.sqrt(dt)[:, None]
            dtheta_m = dtheta_m + profile.arw * sq * rng.standard_normal(dtheta_m.shape)
            dv_m = dv_m + profile.vrw * sq * rng.standard_normal(dv_m.shape)
        yield time_s, dtheta_m, dv_m


def _npy_header(shape: tuple) -> bytes:
    import io

    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return buffer.getvalue()


def _write_npz(windows, meta: dict, target: Path) -> int:
    """Columns go to raw scratch files as they come, then into the zip one member at a time."""
    import json

    names, widths = ("time_s", "dtheta_rad", "dv_mps"), (1, 3, 3)
    scratch = [tempfile.TemporaryFile(dir=target.parent) for _ in names]
    n = 0
    try:
        for window in windows:
            for handle, column in zip(scratch, window):
                handle.write(np.ascontiguousarray(column, dtype="<f8").tobytes())
            n += len(window[0])
        with zipfile.ZipFile(target, "w", zipfile.ZIP_STORED, allowZip64=True) as archive:
            for name, width, handle in zip(names, widths, scratch):
                handle.seek(0)
                with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                    member.write(_npy_header((n,) if width == 1 else (n, width)))
                    while block := handle.read(1 << 24):
                        member.write(block)
            with archive.open("meta.npy", "w") as member:
                np.lib.format.write_array(member, np.array(json.dumps(meta, ensure_ascii=False)))
    finally:
        for handle in scratch:
            handle.close()
    return n


def _write_csv(windows, meta: dict, target: Path) -> int:
    n = 0
    with open(target, "w", encoding="utf-8", newline="\n") as out:
        out.write(f"# format: {FORMAT}\n")
        out.writelines(f"# {k}: {v}\n" for k, v in meta.items() if k != "format")
        out.write("time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n")
        for time_s, dtheta, dv in windows:
            table = np.column_stack([time_s, dtheta, dv]).tolist()
            # repr() reads back to the same float, as calib.runlog writes its CSV.
            out.writelines(",".join(map(repr, row)) + "\n" for row in table)
            n += len(time_s)
    return n


def simulate_to_file(
    path,
    seq: Sequence,
    cfg: SimConfig,
    errors: ErrorModel,
    profile: NoiseProfile,
    setup_rotvec=(0.0, 0.0, 0.0),
    noise: bool = True,
    seed: int | None = None,
    meta_extra: dict | None = None,
    window: int = WINDOW_SAMPLES,
) -> tuple[int, Truth]:
    """Simulate a run window by window into ``path`` (.npz or .csv); nothing is left half-written.

    Returns
    -------
    n_samples : int
    truth : Truth
        For :func:`calib.truth.write_truth` (no flip errors, no optional terms).
    """
    target = Path(path)
    kind = target.suffix.lower()
    if kind not in (".npz", ".csv"):
        raise CalibError(f"unknown run format {target.suffix!r}", str(path), "name the file .csv or .npz")
    meta = run_meta(seq, cfg) | (meta_extra or {})
    windows = sample_windows(seq, cfg, errors, profile, setup_rotvec, noise, seed, window)
    writer = _write_npz if kind == ".npz" else _write_csv
    n = atomic_write_with(target, lambda tmp: writer(windows, meta, Path(tmp)))
    truth = Truth(
        errors=errors,
        setup_rotvec=np.asarray(setup_rotvec, dtype=float),
        flip_errors_deg=np.zeros(len(seq.steps)),
        profile=profile.name,
        seed=seed,
        noise=noise,
    )
    return n, truth
