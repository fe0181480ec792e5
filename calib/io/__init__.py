"""The files the tool reads and writes: atomic writes and hashes, one validator for TOML fields, what
kind of file a user gave.

Modules:

- :mod:`calib.io.fields`: One validator for the fields of the TOML files the tool reads
- :mod:`calib.io.files`: Small file helpers: atomic writes and content hashes
- :mod:`calib.io.kinds`: What kind of file a user gave, so that a wrong one is named as what it is
"""

from calib.io.fields import Fields, check_format_version
from calib.io.files import (
    atomic_write_bytes,
    atomic_write_file,
    atomic_write_text,
    atomic_write_with,
    check_writable_dir,
    default_mode,
    load_toml,
    remove_quietly,
    sha256_file,
    toml_number,
)
from calib.io.kinds import expect, kind_of

__all__ = [
    "Fields",
    "atomic_write_bytes",
    "atomic_write_file",
    "atomic_write_text",
    "atomic_write_with",
    "check_format_version",
    "check_writable_dir",
    "default_mode",
    "expect",
    "kind_of",
    "load_toml",
    "remove_quietly",
    "sha256_file",
    "toml_number",
]
