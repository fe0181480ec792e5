"""The ``.rrd`` file: a headless rerun stream written atomically, and read back.

:class:`Writer` logs static archetypes and time columns on the one timeline
``time`` and counts what it wrote (:class:`Summary`); :func:`read_recording`
reads a recording back with rerun's own reader.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib.errors import CalibError
from calib.io.files import default_mode, remove_quietly

TIMELINE = "time"
APPLICATION_ID = "seqdesign"


@dataclass
class Summary:
    """What a recording holds (also what ``view --json`` prints)."""

    path: str
    entities: dict[str, int] = field(default_factory=dict)  # entity path -> rows (static = 1)
    notes: list[str] = field(default_factory=list)
    scene_source: str = ""
    mount_source: str = ""

    def to_dict(self) -> dict:
        return {
            "rrd": self.path,
            "scene_source": self.scene_source,
            "mount_source": self.mount_source,
            "entities": dict(self.entities),
            "notes": list(self.notes),
        }


class Writer:
    """A headless recording stream saving to a temporary file beside ``path``.

    ``commit()`` flushes and moves the file into place in one step; on any
    error the temporary file is removed and ``path`` is left as it was.
    """

    def __init__(self, path: str | os.PathLike, recording_id: str, name: str, blueprint):
        import rerun as rr

        self.rr = rr
        self.target = Path(path)
        if self.target.suffix.lower() != ".rrd":
            raise CalibError(
                f"unknown recording format {self.target.suffix!r}",
                str(self.target),
                "name the recording .rrd",
            )
        directory = self.target.parent
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{self.target.name}.", suffix=".tmp", dir=directory)
        except OSError as exc:
            raise CalibError(
                f"cannot write the file: {exc.strerror or exc}",
                str(self.target),
                "check that the directory exists and is writable",
            ) from None
        os.close(fd)
        self.tmp = tmp
        self.summary = Summary(path=str(self.target))
        self._static_only: set[str] = set()
        try:
            rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
            rec.set_log_time_enabled(False)
            rec.set_log_tick_enabled(False)
            rec.save(tmp, default_blueprint=blueprint)
            rec.send_recording_name(name)
        except BaseException:
            remove_quietly(tmp)
            raise
        self.rec = rec

    # -- logging helpers -------------------------------------------------

    def static(self, entity: str, *archetypes) -> None:
        for a in archetypes:
            self.rec.log(entity, a, static=True)
        if entity not in self.summary.entities:
            self.summary.entities[entity] = 1
            self._static_only.add(entity)

    def columns(self, entity: str, times: np.ndarray, columns) -> None:
        rr = self.rr
        self.rec.send_columns(
            entity,
            indexes=[rr.TimeColumn(TIMELINE, duration=np.asarray(times, dtype=np.float64))],
            columns=columns,
        )
        if entity in self._static_only:
            self._static_only.discard(entity)
            self.summary.entities[entity] = 0
        self.summary.entities[entity] = self.summary.entities.get(entity, 0) + len(times)

    def series(self, entity: str, times: np.ndarray, values: np.ndarray, names, colors=None) -> None:
        """A multi-channel time series: one entity, one row per time, ``names`` per channel."""
        rr = self.rr
        values = np.asarray(values, dtype=np.float64)
        if values.ndim == 1:
            values = values[:, None]
        self.static(entity, rr.SeriesLines(names=list(names), colors=colors, widths=[1.0] * len(names)))
        self.columns(entity, times, rr.Scalars.columns(scalars=values))

    def note(self, text: str) -> None:
        self.summary.notes.append(text)

    # -- finishing -------------------------------------------------------

    def commit(self) -> Summary:
        try:
            self.rec.flush()
            self.rec.disconnect()
            with open(self.tmp, "rb+") as handle:
                os.fsync(handle.fileno())
            os.chmod(self.tmp, default_mode(self.target))
            os.replace(self.tmp, self.target)
        except OSError as exc:
            remove_quietly(self.tmp)
            raise CalibError(
                f"cannot write the file: {exc.strerror or exc}",
                str(self.target),
                "check free disk space and permissions",
            ) from None
        except BaseException:
            self.abort()
            raise
        return self.summary

    def abort(self) -> None:
        try:
            self.rec.disconnect()
        except Exception:  # noqa: BLE001 - nothing more to do for a file we throw away
            pass
        remove_quietly(self.tmp)


def recording_id(*parts) -> str:
    """A recording id derived from the content, so re-recording the same input gives the same id."""
    h = hashlib.sha256()
    for p in parts:
        h.update(np.ascontiguousarray(p).tobytes() if isinstance(p, np.ndarray) else repr(p).encode())
    return str(uuid.UUID(bytes=h.digest()[:16], version=5))


def read_recording(path: str | os.PathLike) -> dict[str, list]:
    """Every chunk of an ``.rrd``'s recording, as pyarrow record batches by entity path.

    Uses rerun's own reader (``rerun.chunk.RrdReader``). Entity paths are
    returned without their leading ``/``.
    """
    from rerun.chunk import RrdReader

    out: dict[str, list] = {}
    for chunk in RrdReader(str(path)).stream():
        out.setdefault(chunk.entity_path.lstrip("/"), []).append(chunk.to_record_batch())
    return out
