"""Reading a rerun recording back with rerun's own reader: what a test of a recording asserts on."""

from __future__ import annotations

import numpy as np


def read_back(path) -> dict[str, list]:
    from rerun.chunk import RrdReader

    out: dict[str, list] = {}
    for chunk in RrdReader(str(path)).stream():
        out.setdefault(chunk.entity_path.lstrip("/"), []).append(chunk.to_record_batch())
    return out


def batch_with(rec, entity, column):
    found = [b for b in rec[entity] if column in b.schema.names]
    assert len(found) == 1, (entity, column, [b.schema.names for b in rec[entity]])
    return found[0]


def times_of(batch) -> np.ndarray:
    return batch.column("time").cast("int64").to_numpy() / 1e9


def scalars(rec, entity):
    b = batch_with(rec, entity, "Scalars:scalars")
    flat = b.column("Scalars:scalars").flatten().to_numpy()
    return times_of(b), flat.reshape(b.num_rows, -1)


def matrices(batch) -> np.ndarray:
    """Transform3D:mat3x3 rows as (n, 3, 3); rerun stores each matrix column-major."""
    flat = batch.column("Transform3D:mat3x3").flatten().flatten().to_numpy()
    return flat.astype(float).reshape(-1, 3, 3).transpose(0, 2, 1)


def tensor(batch, column) -> np.ndarray:
    """A BarChart or Tensor cell: its flat buffer reshaped by its stored shape."""
    cell = batch.column(column).to_pylist()[0][0]
    return np.array(cell["buffer"], dtype=float).reshape([int(n) for n in cell["shape"]])


def bars(rec, entity) -> np.ndarray:
    return tensor(batch_with(rec, entity, "BarChart:values"), "BarChart:values")


def text_of(rec, entity) -> str:
    return batch_with(rec, entity, "TextDocument:text").column("TextDocument:text").to_pylist()[0][0]
