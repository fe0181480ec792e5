"""What particular loggers write that no check of the data can tell: said where their names are seen.

Apple's Core Motion gives the acceleration with the opposite sign to Android's and to this
tool's specific force (``-1 g`` on z lying face up, in g): an iOS logger's accelerometer
columns (SensorLog's ``accelerometerAccelerationX(G)``...) are the specific force negated.
A calibration by hand cannot see it: the three axes reversed together turn as the gyro says,
and every bias and g-sensitivity term comes out with its sign reversed. So the map must
negate them (``accelerometerAccelerationX(G)=-accel_x_g``, docs/logs-columns.md), and a map
that does not is warned of by name.
"""

from __future__ import annotations

from .columns import NEGATED, sensor_of

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
