"""What particular loggers write that no check of the data can tell: said where their names are seen.

Apple's Core Motion gives the acceleration with the opposite sign to Android's and to this
tool's specific force (``-1 g`` on z lying face up, in g): an iOS logger's accelerometer
columns (SensorLog's ``accelerometerAccelerationX(G)``...) are the specific force negated.
A calibration by hand cannot see it: the three axes reversed together turn as the gyro says,
and every bias and g-sensitivity term comes out with its sign reversed. So the map must
negate them (``accelerometerAccelerationX(G)=-accel_x_g``, docs/logs-columns.md), and a map
that does not is warned of by name.

Some loggers write their IMU's columns under names fixed by their own convention, in fixed units
(`KNOWN_HEADERS`): EuRoC's (and Kalibr's, TUM-VI's) ``imu0.csv``, ROS's ``rostopic echo -p`` and
a ROS bag's IMU topic exported to CSV. Given no column map, such a header is read as its
convention says (rad/s, m/s^2, stamps in ns), said on stderr (`known_header_map`).

Xsens MT Manager's older exports state their output rate in a ``//`` line of the preamble
(``// Update Rate: 100.0Hz``): a sample counter no other rate times takes it, said
(`with_logger_rate`); a 2022 export states none, and is pointed to its own clock.
"""

from __future__ import annotations

import warnings

from calib.errors import CalibError

from .columns import COUNTER, NEGATED, ColumnPlan, sensor_of
from .counter import RATE_FIX
from .text import header_names, is_comment, logger_rate

# Prefixes of the accelerometer columns of iOS loggers (Apple's sign): SensorLog.
APPLE_SIGN_PREFIXES = ("accelerometerAcceleration",)


def apple_sign_warning(mapping: dict[str, str], where: str) -> str | None:
    """The warning for an iOS logger's accelerometer mapped without its sign reversed, or None."""
    plain = [
        (source, target)
        for source, target in mapping.items()
        if source.startswith(APPLE_SIGN_PREFIXES)
        and sensor_of(target) == "accel"
        and not target.startswith(NEGATED)
    ]
    if not plain:
        return None
    source, target = plain[0]
    return (
        f"{where}: '{source}' is an iOS logger's acceleration, which Apple gives with the sign reversed "
        f"(-1 g on z lying face up); map it negated, {source}={NEGATED}{target} (and the other axes "
        "alike), or every accelerometer bias comes out with its sign reversed"
    )


def _axes(prefix: str, suffix: str, target: str) -> dict[str, str]:
    """A logger's three axis names (``prefix`` x/y/z ``suffix``) mapped to the grammar's ``target``."""
    return {f"{prefix}{a}{suffix}": target.format(a) for a in "xyz"}


GYRO, ACCEL = "gyro_{}_radps", "accel_{}_mps2"
# The loggers whose IMU headers are known, each its names mapped to the grammar's: the sensor's
# own stamp where the file has one (a ROS message's header.stamp, not the time it was logged).
KNOWN_HEADERS = (
    (
        "EuRoC's imu0.csv (Kalibr, TUM-VI)",
        {"timestamp [ns]": "time_ns"}
        | _axes("w_RS_S_", " [rad s^-1]", GYRO)
        | _axes("a_RS_S_", " [m s^-2]", ACCEL),
    ),
    (
        "ROS's rostopic echo -p of a sensor_msgs/Imu topic",
        {"field.header.stamp": "time_ns"}
        | _axes("field.angular_velocity.", "", GYRO)
        | _axes("field.linear_acceleration.", "", ACCEL),
    ),
    (
        "a ROS bag's sensor_msgs/Imu topic exported to CSV",
        {"header.stamp.secs": "time_s", "header.stamp.nsecs": "time_ns"}
        | _axes("angular_velocity.", "", GYRO)
        | _axes("linear_acceleration.", "", ACCEL),
    ),
    (
        "a ROS 2 bag's sensor_msgs/Imu topic exported to CSV",
        {"header.stamp.sec": "time_s", "header.stamp.nanosec": "time_ns"}
        | _axes("angular_velocity.", "", GYRO)
        | _axes("linear_acceleration.", "", ACCEL),
    ),
)


# A sensor's own file whose header is known: phyphox's export of its accelerometer ("Acceleration
# with g"; its "Linear Acceleration" leaves gravity out and is not read) and of its gyroscope.
KNOWN_SENSOR_HEADERS = (
    (
        "phyphox's export",
        {
            "accel": {"Time (s)": "time_s"} | _axes("Acceleration ", " (m/s^2)", ACCEL),
            "gyro": {"Time (s)": "time_s"} | _axes("Gyroscope ", " (rad/s)", GYRO),
        },
    ),
)


def _first_known(headers: list[list[str]], known, said: str, name: str, stacklevel: int) -> dict[str, str]:
    """The map of the first ``(logger, mapping)`` in ``known`` whose names a header holds, said on
    stderr (``said``: how its units are read); else empty.
    """
    for names in headers:
        for logger, mapping in known:
            if all(k in names for k in mapping):
                warnings.warn(
                    f"{name}: the columns of {logger}, {said}; "
                    "give the CLI's --columns to map them otherwise",
                    stacklevel=stacklevel + 1,
                )
                return dict(mapping)
    return {}


def known_sensor_map(names: list[str], sensor: str, name: str) -> dict[str, str]:
    """The column map of one sensor's file under a known header (`KNOWN_SENSOR_HEADERS`), said on
    stderr; else empty.
    """
    known = [(logger, maps[sensor]) for logger, maps in KNOWN_SENSOR_HEADERS]
    return _first_known([names], known, "read as its names say (s, rad/s, m/s^2)", name, 4)


def known_header_map(lines: list[str], header_index: int, name: str) -> dict[str, str]:
    """The column map of a known logger's header (`KNOWN_HEADERS`), said on stderr; else empty.

    The header is the row at ``header_index``, or a comment line right above it (EuRoC's
    ``#timestamp [ns],w_RS_S_x [rad s^-1],...``).
    """
    candidates = [header_names(lines[header_index])] if header_index < len(lines) else []
    if header_index > 0 and is_comment(lines[header_index - 1]):
        candidates.append(header_names(lines[header_index - 1].lstrip().lstrip("#/% \t")))
    said = "read as its convention says (rad/s, m/s^2, stamps in ns)"
    return _first_known(candidates, KNOWN_HEADERS, said, name, 3)


XSENS_FINE_TIME = "SampleTimeFine"  # Xsens' sample time, in ticks of its 10 kHz clock


def with_logger_rate(
    options: dict, plan: ColumnPlan, stated: bool, lines, header_index: int, name: str
) -> dict:
    """The options with the rate a logger's preamble states, for a counter no other rate times.

    Only a counter takes it: a time column's stamps carry their own rate (docs/logs.md),
    which a rounded "100.0Hz" would contradict by the crystal's ppm.
    """
    if plan.time_name != COUNTER or stated:
        return options
    found = logger_rate(lines, header_index)
    if found is None:
        if XSENS_FINE_TIME in header_names(lines[header_index]):
            raise CalibError(
                "the sample counter says no time without the rate, and this Xsens export states none",
                f"{name}, line {header_index + 1}",
                f"time the samples by the sensor's own clock: map {XSENS_FINE_TIME}=time_100us "
                "(its 10 kHz ticks) in place of the counter; or " + RATE_FIX,
            )
        return options
    rate, line = found
    warnings.warn(
        f"{name}, line {line}: the sample counter is timed at the {rate:g} Hz this line states "
        f"({lines[line - 1].strip()!r}); give the CLI's --sample-rate-hz for another rate",
        stacklevel=3,
    )
    return {**options, "sample_rate_hz": rate}
