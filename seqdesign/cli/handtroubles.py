"""The ``--by-hand`` options that add a real hand recording's troubles (calib.hand.troubles).

Shared by ``simulate --by-hand`` and ``verify --by-hand``: tremor of the poses held in the
hand, host time stamps that jitter or count epoch milliseconds, a gyro g-sensitivity and a
sample-clock rate error. All off by default.
"""

from __future__ import annotations

import math

import click

from calib.errors import CalibError

from .options import together

# Each option's parameter name and its default (given without --by-hand, they are refused).
TROUBLE_DEFAULTS = {
    "tremor_deg": 0.0,
    "hand_held_s": None,
    "shake_mps2": None,
    "stamp_jitter_ms": 0.0,
    "stamps": "seconds",
    "g_sensitivity_dphg": None,
    "rate_error": 0.0,
}


def _trouble(flag: str, **kw):
    """One trouble option, its default the one :data:`TROUBLE_DEFAULTS` holds for its parameter."""
    return click.option(flag, default=TROUBLE_DEFAULTS[flag[2:].replace("-", "_")], **kw)


def trouble_options(command):
    """Add the trouble options to a command (into the parameters of :data:`TROUBLE_DEFAULTS`)."""
    options = [
        _trouble(
            "--tremor-deg",
            type=click.FloatRange(0.0, 5.0),
            help="--by-hand: the poses are held in the hand; RMS tremor angle per axis, deg "
            "(a hand: 0.05-0.5; 3-12 Hz).",
        ),
        _trouble(
            "--hand-held-s",
            type=click.FloatRange(0.0, min_open=True),
            help="--by-hand with --tremor-deg: only the poses that begin in the first this many "
            "seconds are held in the hand (default: all).",
        ),
        _trouble(
            "--shake-mps2",
            type=click.FloatRange(0.0, 5.0),
            help="--by-hand with --tremor-deg: RMS shake acceleration per axis of a held pose, "
            "m/s^2 [default: 0.05].",
        ),
        _trouble(
            "--stamp-jitter-ms",
            type=click.FloatRange(0.0, 1000.0),
            help="--by-hand: the time column holds a host's reception times, each sample up to "
            "this late (uniform), in order (default 0: the nominal sample times).",
        ),
        _trouble(
            "--stamps",
            type=click.Choice(["seconds", "epoch-ms"]),
            help="--by-hand: the time column in float seconds from the start, or in integer "
            "UNIX milliseconds (a .csv time_ms column).",
        ),
        _trouble(
            "--g-sensitivity-dphg",
            metavar="S|G9",
            help="--by-hand: gyro g-sensitivity, deg/h/g: one number S (each of the 9 terms drawn "
            "within +-S) or 9 comma-separated values gsxx,gsxy,...,gszz.",
        ),
        _trouble(
            "--rate-error",
            type=click.FloatRange(-0.2, 0.2),
            help="--by-hand: the IMU samples this fraction faster than its nominal rate "
            "(0.01: 1 %); the log keeps the nominal rate.",
        ),
    ]
    return together(*options)(command)


def given_troubles(values: dict) -> list[str]:
    """The trouble options given (not at their defaults), as ``--name``."""
    return ["--" + k.replace("_", "-") for k, v in values.items() if v != TROUBLE_DEFAULTS[k]]


def parse_g_sensitivity(text: str | None) -> float | tuple[float, ...] | None:
    """``--g-sensitivity-dphg``: one half-range, or 9 values; refused naming the option."""
    if text is None:
        return None
    fields = [t.strip() for t in str(text).split(",")]
    try:
        values = tuple(float(t) for t in fields)
    except ValueError:
        values = ()
    if len(values) not in (1, 9) or not all(math.isfinite(v) for v in values):
        raise CalibError(
            f"--g-sensitivity-dphg {text!r} is not one number or 9 comma-separated numbers",
            "--g-sensitivity-dphg",
            "give e.g. 300 (each term drawn within +-300 deg/h/g) or 9 values gsxx,gsxy,...,gszz",
        )
    if max(abs(v) for v in values) > 1e4:
        raise CalibError(
            f"--g-sensitivity-dphg {text!r} beyond 10000 deg/h/g",
            "--g-sensitivity-dphg",
            "a MEMS gyro's g-sensitivity is tens to hundreds of deg/h/g",
        )
    if len(values) == 1:
        if values[0] < 0:
            raise CalibError(
                "--g-sensitivity-dphg: a half-range must be >= 0",
                "--g-sensitivity-dphg",
                "give its size, or 9 signed values",
            )
        return values[0]
    return values


def trouble_spec(values: dict):
    """The :class:`calib.hand.troubles.TroubleSpec` of the options' values; bad combinations refused."""
    from calib.hand.tremor import SHAKE_MPS2
    from calib.hand.troubles import TroubleSpec

    tremor = values["tremor_deg"]
    if not tremor:
        if given := [n for n in ("hand_held_s", "shake_mps2") if values[n] is not None]:
            names = ", ".join("--" + n.replace("_", "-") for n in given)
            raise CalibError(f"{names} given without --tremor-deg", names, "add --tremor-deg DEG, or drop it")
    return TroubleSpec(
        tremor_deg=tremor,
        hand_held_s=values["hand_held_s"],
        shake_mps2=SHAKE_MPS2 if values["shake_mps2"] is None else values["shake_mps2"],
        g_sensitivity_dphg=parse_g_sensitivity(values["g_sensitivity_dphg"]),
        rate_error=values["rate_error"],
        stamp_jitter_s=values["stamp_jitter_ms"] / 1000.0,
        stamps=values["stamps"],
    )
