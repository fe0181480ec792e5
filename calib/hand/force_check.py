"""The accelerometer's unit mistakes, told by ``|f|`` at rest against the site's gravity.

At rest the accelerometers read gravity: ``|f|`` is ``g`` to a few per cent whatever the
unit's errors. Read in another unit it is ``g`` times that unit's factor (g read as m/s^2:
1.0; milli-g: 1000); near 0 the logger took gravity out; a converter's raw counts give its
counts per g; a zero offset spreads ``|f|`` over the poses on a sphere about the offset.
"""

from __future__ import annotations

import math

import numpy as np

from calib.model.params import STANDARD_GRAVITY

from .mistake import Mistake

# Unit mistakes of an accelerometer: (what its column holds, what it is read as, |f| at rest the
# mistake gives in "m/s^2" over the site's gravity, the unit to name the columns by).
_FORCE_MISTAKES = (
    ("g", "m/s^2", 1.0 / STANDARD_GRAVITY, "g"),
    ("m/s^2", "g", STANDARD_GRAVITY, "mps2"),
    ("mg (milli-g)", "m/s^2", 1000.0 / STANDARD_GRAVITY, "mg"),
    ("mg (milli-g)", "g", 1000.0, "mg"),
)
GRAVITY_REMOVED = 0.1  # |f| at rest below this fraction of g: the logger took gravity out
# The counts per g of converters' usual ranges (16-bit at +-2, 4, 8, 16 g; 10-13-bit parts): |f| at
# rest within 10 % of one of them, read as m/s^2, is raw counts (no unit is that far from g).
COUNTS_PER_G = (16384, 8192, 4096, 2048, 1024, 512, 256)


# |f| at rest spreading over the rests by more than this (max - min over the median) is no scale
# error (a MEMS accelerometer's few per cent move it by less than a tenth)...
ZERO_SPREAD = 0.2
# ...and a sphere through the rests' specific force this close (RMS over its radius) says that the
# accelerometer reads about its own constant, not about zero: a zero offset.
ZERO_SPHERE_FIT = 0.03
# ...and the rests must spread gravity over all three axes (RMS about their mean along the least
# spread direction, over g) for the centre to be known in all three.
ZERO_SPAN = 0.15


def zero_mistake(
    f_rests: np.ndarray, gravity_mps2: float, conversion, least_g: float = 0.0
) -> Mistake | None:
    """The accelerometer's zero, when its rests lie on a sphere of radius about g off the origin.

    ``least_g`` is the least offset named, in g (0: any the spread of ``|f|`` shows).

    A wrong zero (counts read with another unit's zero, an offset left in) makes ``|f|`` depend on
    the pose; a unit or scale mistake scales every pose alike. Gravity at every rest is a point
    on a sphere of radius g about the reading of zero force: its centre is the offset.
    """
    norms = np.linalg.norm(f_rests, axis=1)
    if len(f_rests) < 6 or np.ptp(norms) < ZERO_SPREAD * np.median(norms):
        return None
    # The sphere's centre is found only along directions the rests span: rests turned about one
    # axis leave it free along that axis (a wrong offset would be named).
    spread = np.linalg.svd(f_rests - f_rests.mean(axis=0), compute_uv=False) / math.sqrt(len(f_rests))
    if spread.min() < ZERO_SPAN * gravity_mps2:
        return None
    # |f|^2 = 2 f.c + (R^2 - |c|^2): linear in (c, d) (an algebraic fit; its residuals judged below).
    A = np.column_stack([2.0 * f_rests, np.ones(len(f_rests))])
    (cx, cy, cz, d), *_ = np.linalg.lstsq(A, norms**2, rcond=None)
    centre = np.array([cx, cy, cz])
    radius = math.sqrt(max(d + centre @ centre, 0.0))
    misfit = np.linalg.norm(f_rests - centre, axis=1) - radius
    if radius < 0.5 * gravity_mps2 or np.sqrt(np.mean(misfit**2)) > ZERO_SPHERE_FIT * radius:
        return None  # no sphere of gravity's size: gravity taken out, or no offset
    if np.linalg.norm(centre) < least_g * gravity_mps2:
        return None  # a bias the fit estimates (a cheap part's 50-150 mg), not a zero to set
    g = gravity_mps2
    lo, hi = norms.min() / g, norms.max() / g
    at = ", ".join(f"{c / g:+.3g}" for c in centre)
    said = (
        f"|f| at the {len(f_rests)} still stretches runs from {lo:.3g} g to {hi:.3g} g: no unit's mistake, "
        f"a zero offset. A sphere through them has radius {radius / g:.4g} g and its centre, the "
        f"accelerometer's reading of no force, at ({at}) g"
    )
    if conversion is not None:
        zero = conversion.to_counts(centre[None, :], "accel")[0]
        fix = f"set the conversion's accelerometer zero_counts to [{', '.join(f'{z:.0f}' for z in zero)}]"
    else:
        fix = f"subtract ({', '.join(f'{c:.4g}' for c in centre)}) m/s^2 from the accelerometer columns"
    if abs(radius / g - 1.0) > 0.15:
        fix += f", and check its unit (the radius is {radius / g:.3g} g, not 1)"
    return Mistake(
        said, np.eye(3), np.eye(3), cannot_fix=fix + "; the fit then estimates what is left as the bias"
    )


def force_mistake(f: float, gravity_mps2: float) -> Mistake:
    """The mistake an accelerometer's ``|f|`` at rest (``f``, as read) names: a unit, or gravity taken out.

    A known unit mistake is told by a ratio within 10 % (a unit's errors are a few per cent) and
    undone exactly by its factor. ``|f|`` near zero is no unit: a phone's "linear" or "user"
    acceleration has gravity subtracted, and the 21 cannot be had from it. Any other ratio is
    no mistake we can name: scaling it to g would hide the scale factors it should show.
    """
    eye = np.eye(3)
    ratio = f / gravity_mps2
    for holds, read_as, expected, unit in _FORCE_MISTAKES:
        if abs(ratio / expected - 1.0) < 0.1:
            return Mistake(
                f"|f| at rest is {f:.4g}, not {gravity_mps2:.4g} m/s^2: the accelerometer is in {holds} "
                f"and read as {read_as} (name its columns accel_<axis>_{unit})",
                eye,
                eye / expected,
            )
    if ratio < GRAVITY_REMOVED:
        return Mistake(
            f"|f| at rest is {f:.3g} m/s^2, not g ({gravity_mps2:.4g}): the accelerometer reads no "
            "gravity; the logger has taken it out (a phone's 'linear' or 'user' acceleration)",
            eye,
            eye,
            cannot_fix="log the accelerometer's raw specific force, gravity included (a phone's "
            "'accelerometer' or 'total acceleration', not its 'linear acceleration')",
        )
    counts = next((c for c in COUNTS_PER_G if abs(f / c - 1.0) < 0.1), None)
    if counts is not None:
        return Mistake(
            f"|f| at rest is {f:.4g} in the log's unit, {ratio:.3g} g if it were m/s^2: raw converter "
            f"counts, as an accelerometer of {counts} counts per g reads",
            eye,
            eye,
            cannot_fix=f'read it as counts with a conversion (counts_per_unit {counts}, unit = "g"): columns '
            "accel_<axis>_counts, or imu_tk's files with the CLI's --conversion FILE, not si",
        )
    return Mistake(
        f"|f| at rest is {f:.4g} m/s^2, {ratio:.3g} g, which no unit mistake we know of gives",
        eye,
        eye,
        cannot_fix="check the accelerometer's unit and its conversion (zero and counts per unit): "
        "at rest it must read about g",
    )
