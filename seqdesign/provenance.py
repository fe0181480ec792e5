"""Provenance of what a library call writes: the tool's version, the call, the inputs' SHA-256.

The CLI records the command line instead (:func:`seqdesign.cli.tools.provenance`);
a file written from a notebook records the call that made it.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from calib.io.files import sha256_file
from calib.sequence.definition import resolve_sequence_path


def tool_version() -> str:
    """The installed package's version."""
    try:
        return version("seqdesign")
    except PackageNotFoundError:
        return "0+unknown"


def call_provenance(call: str, inputs: dict | None = None, **extra) -> dict:
    """Tool version, the call (e.g. ``seqdesign.api.export('paper-9pos')``), SHA-256 of each input file."""
    out = {"tool_version": tool_version(), "command": call}
    for key, path in (inputs or {}).items():
        if path is None:
            continue
        if key == "sequence":  # a shipped name (paper-9pos) hashes its file
            path = resolve_sequence_path(path)
        out[f"{key}_sha256"] = sha256_file(path)
    out.update({k: v for k, v in extra.items() if v is not None})
    return out
