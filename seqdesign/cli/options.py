"""Options several commands share, declared once: the site, noise, requirements, terms, output, columns.

Each takes the help text of its command where the meaning differs (a latitude that
overrides a sequence's, or fills in a logger's CSV); the name, type and limits are one.
The site limits are calib.nav.earth's, so the CLI refuses what the library would.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, fields

import click

from calib.nav.earth import HEIGHT_RANGE_M, MAX_LATITUDE_DEG

LATITUDE = click.FloatRange(-MAX_LATITUDE_DEG, MAX_LATITUDE_DEG)
HEIGHT = click.FloatRange(*HEIGHT_RANGE_M)
GRAVITY = click.FloatRange(9.7, 9.9, min_open=True, max_open=True)
TOLERANCE = click.FloatRange(0.0, 10.0)

as_json = click.option("--json", "as_json", is_flag=True, help="One JSON document on stdout.")


def latitude(help: str = "Site latitude, deg (default: the sequence's, else 40).", default=None):
    """``--latitude`` (deg)."""
    return click.option(
        "--latitude", type=LATITUDE, default=default, show_default=default is not None, help=help
    )


def height(help: str = "Site height, m (default: the sequence's, else 0)."):
    """``--height`` (m)."""
    return click.option("--height", type=HEIGHT, help=help)


def gravity(help: str = "Measured site gravity, m/s^2 (default: WGS-84 normal gravity)."):
    """``--gravity`` (m/s^2), into ``gravity_mps2``."""
    return click.option("--gravity", "gravity_mps2", type=GRAVITY, help=help)


def profile(
    help: str = "Noise profile: built-in name (navigation, navigation-gm, tactical, mems) or TOML file.",
):
    """``--profile``, default navigation."""
    return click.option("--profile", default="navigation", show_default=True, help=help)


requirements = click.option(
    "--requirements",
    "requirements",
    default=None,
    metavar="FILE|NAME",
    help="Accuracy requirements: a TOML file with a [requirements] table (spec names and "
    "units; missing ones keep the paper's) or paper, tactical, mems. Default: those of the "
    "profile's grade (paper for a navigation-grade one; docs/grades.md), mems by hand.",
)


def with_terms(help: str):
    """``--with`` terms beyond the 21 (lever-arm, k2, time-offset, all), into ``with_terms``."""
    return click.option("--with", "with_terms", default=None, metavar="TERMS", help=help)


def tolerance(
    help: str = "Base mounting tolerance; the figures are the worst over the box (0: nominal only).",
):
    """``--tolerance-deg``, default 3 (the conventions' setup tolerance)."""
    return click.option("--tolerance-deg", type=TOLERANCE, default=3.0, show_default=True, help=help)


# The gimbals shipped in sequences/gimbals/ (a test holds the list to the folder).
SHIPPED_GIMBALS = "slip-rings, cable-wrap"


def gimbal(help: str):
    """``--gimbal``, a shipped name or a description file, into ``gimbal_file``.

    ``help`` says what the command does with it; what the value may be is said here, once.
    """
    return click.option(
        "--gimbal",
        "gimbal_file",
        default=None,
        metavar="NAME|FILE",
        help=f"{help} A shipped gimbal ({SHIPPED_GIMBALS}) or a TOML file (docs/gimbal.md).",
    )


def seed(help: str = "Random seed (noise, setup, flip errors)."):
    """``--seed``."""
    return click.option("--seed", type=int, default=None, help=help)


def sample_rate():
    """``--sample-rate-hz`` of a simulated run."""
    return click.option(
        "--sample-rate-hz",
        type=click.FloatRange(1.0, 10000.0),
        default=200.0,
        show_default=True,
        help="Output rate of the simulated IMU, Hz.",
    )


columns = click.option(
    "--columns",
    "columns",
    default=None,
    metavar="MAP",
    # The example is short enough to stay on one line of the help (a longer one was cut mid-word).
    help="Map a logger CSV's own column names to ours (docs/logs-columns.md): comma-separated "
    "FILE_NAME=OUR_NAME pairs, e.g. t=time_ms,gx=gyro_x_dps,ax=accel_x_g and so on for gy, "
    "gz, ay, az; our name's suffix gives the unit (time_s, time_ms, time_us, time_ns; radps, "
    "dps, mdps; mps2, g, mg).",
)


def file_path(flag: str, dest: str, help: str, **kw):
    """An option that names a file (not a folder), into ``dest`` (``kw``: click's ``required``,
    ``metavar``, ...).
    """
    return click.option(flag, dest, type=click.Path(dir_okay=False), help=help, **kw)


gyro_file = file_path(
    "--gyro-file",
    "gyro_file",
    "The gyro's own file: RUN is then the accelerometer's. Two CSV files with headers, each "
    "its time and its sensor (--columns maps both), or imu_tk's 't x y z' rows in raw counts "
    "without a header (give --conversion; --conversion si for rows already in m/s^2 and rad/s). "
    "Each is read on its own clock (docs/logs-columns.md).",
    default=None,
    metavar="FILE",
)

conversion = file_path(
    "--conversion",
    "conversion",
    "Nominal conversion of raw counts to SI (zero and counts per unit, per sensor and axis): "
    "a TOML with [gyro] and [accel], or imu_tk's nominal-values text. Needed by columns in "
    "counts (gyro_x_counts, accel_x_counts) and by --gyro-file; the word si for imu_tk files "
    "already in m/s^2 and rad/s.",
    default=None,
    metavar="FILE",
)


def log_sample_rate(
    help: str = "The IMU's sample rate, Hz, for a log that does not state it: needed by a "
    "sample counter column (n_samples=counter).",
):
    """``--sample-rate-hz`` of a log that does not state it (None when not given)."""
    return click.option(
        "--sample-rate-hz",
        "sample_rate_hz",
        type=click.FloatRange(0.0, min_open=True),
        default=None,
        help=help,
    )


def together(*decorators):
    """One decorator that applies ``decorators`` as if listed in this order above a command."""

    def apply(command):
        for decorator in reversed(decorators):
            command = decorator(command)
        return command

    return apply


@dataclass(frozen=True)
class LogReading:
    """How a logger's file is read: ``--columns``, ``--gyro-file``, ``--conversion``,
    ``--sample-rate-hz`` (None: not given), ``--at-stamps``.
    """

    columns: str | None = None
    gyro_file: str | None = None
    conversion: str | None = None
    sample_rate_hz: float | None = None
    at_stamps: bool = False

    @property
    def by_hand(self) -> dict:
        """The reader's keyword arguments of the options but the columns (empty when none is given)."""
        given = {
            "gyro_path": self.gyro_file,
            "conversion": self.conversion,
            "sample_rate_hz": self.sample_rate_hz,
            "at_stamps": self.at_stamps or None,
        }
        return {key: value for key, value in given.items() if value is not None}

    @property
    def reader(self) -> dict:
        """The keyword arguments of :func:`calib.runlog.read_run`: the columns and those given."""
        return {"columns": self.columns, **self.by_hand}

    @property
    def logger(self) -> bool:
        """Whether the file is a logger's own (any of the four given): it is read whole."""
        return bool(self.columns or self.by_hand)


# correct, score and analyze LOG: the log's lost samples filled where it is still, as the readers'
# refusals say (calibrate's own --allow-gaps also guesses a sample lost amid a turn, by hand).
fill_gaps = click.option(
    "--allow-gaps",
    is_flag=True,
    help="Fill samples the log lost at rest (said) and drop exact duplicates; a sample lost amid a "
    "turn is still refused.",
)


at_stamps = click.option(
    "--at-stamps",
    is_flag=True,
    help="The rows were sampled at their stamps (a logger that reads the sensor when its loop comes "
    "round): read each over its own stamp interval, whatever pattern its stamps keep.",
)


def log_reading(command):
    """``--columns``, ``--gyro-file``, ``--conversion``, ``--sample-rate-hz`` and ``--at-stamps``,
    given to the command as one parameter ``reading`` (a :class:`LogReading`).
    """
    names = [f.name for f in fields(LogReading)]

    @functools.wraps(command)
    def run(*args, **kwargs):
        kwargs["reading"] = LogReading(**{name: kwargs.pop(name) for name in names})
        return command(*args, **kwargs)

    return together(columns, gyro_file, conversion, log_sample_rate(), at_stamps)(run)


# The site of a logger's CSV that does not carry it, and how the file is read (calibrate, correct).
log_site_and_reading = together(
    latitude("Site latitude, deg, for a logger's CSV that does not carry latitude_deg."),
    height("Site height, m, for a logger's CSV that does not carry height_m."),
    log_reading,
)
