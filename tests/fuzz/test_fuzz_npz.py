"""Fuzzing of the run log's NPZ reader (``read_run``): mutated bytes, random archives
(wrong shapes and dtypes, object arrays, missing arrays, meta that is not JSON), damaged
.npy headers and damaged zip archives.

The contract, the budget and the tally: ``fuzzing.py``.
"""

from __future__ import annotations

import io
import json
import math
import re
import zipfile

import numpy as np
from fuzz_fixtures import bases_fixture, report_tally, work_fixture  # noqa: F401 (fixtures)
from fuzz_text import FLOATS, KEYS, TEXT
from fuzzing import budget, fuzz_case, mutate_bytes
from hypothesis import given, strategies as st

from calib.runlog import make_meta


@budget(300)
@given(data=st.data())
def test_mutated_bytes(data, bases, work):
    fuzz_case("npz", work, mutate_bytes(data, bases["npz"]))


# ---------------------------------------------------------------------------
# Random NPZ archives


def _npz(arrays: dict) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


GOOD_META = json.dumps(make_meta(40.0, 0.0, 10.0))


def _meta_arrays():
    texts = st.one_of(
        st.just(GOOD_META),
        TEXT,
        st.sampled_from(
            [
                "",
                "{}",
                "[]",
                "null",
                "1",
                '"x"',
                "{",
                "[" * 100000,
                '{"a": ' * 100000,
                "1" + "0" * 5000,
                '{"format": "imu-run/1"}',
                GOOD_META.replace("10.0", "NaN"),
                GOOD_META.replace("10.0", "1" + "0" * 5000),
                GOOD_META.replace("10.0", "1e400"),
                GOOD_META.replace('"10.0"', "[10]"),
                GOOD_META.replace('"10.0"', "true"),
                GOOD_META.replace('"10.0"', "null"),
                GOOD_META.replace("40.0", "91"),
                GOOD_META.replace("10.0", "0"),
                GOOD_META.replace("10.0", "1e-320"),
                GOOD_META.replace("imu-run/1", "imu-run/2"),
                GOOD_META + "x",
            ]
        ),
        st.dictionaries(
            KEYS, st.one_of(TEXT, FLOATS, st.integers(), st.booleans(), st.none()), max_size=5
        ).map(lambda d: json.dumps({**make_meta(40.0, 0.0, 10.0), **d})),
    )
    return st.one_of(
        texts.map(np.array),
        texts.map(lambda t: np.array(t.encode("utf-8", "surrogatepass"))),
        st.just(np.array(b"\xff\xfe{")),
        texts.map(lambda t: np.array([t, t])),
        st.just(np.array(1.0)),
        st.just(np.zeros((0,), dtype="U1")),
        st.just(np.array({"format": "imu-run/1"}, dtype=object)),
    )


def _bad_array(n: int, cols: int | None):
    """Arrays a run log must refuse (or, for odd but real dtypes, convert)."""
    shape = (n,) if cols is None else (n, cols)
    good = np.arange(1, n + 1) / 10.0 if cols is None else np.full(shape, 1e-4)
    wrong_shapes = st.sampled_from(
        [(), (0,), (n + 1,), (n - 1,), (n, 2), (n, 4), (3, n), (n, 3, 1), (1, n), (n, 1)]
    ).map(np.ones)
    dtypes = st.sampled_from(
        [
            "f2",
            "f4",
            "i1",
            "i8",
            "u8",
            "?",
            "c16",
            "U3",
            "S3",
            "M8[s]",
            "m8[s]",
            "V8",
            np.longdouble,
            [("a", "f8")],
        ]
    )
    special = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 0.0, -1.0])

    def poisoned(args):
        value, index = args
        out = good.copy()
        out.flat[index % out.size] = value
        return out

    def typed(dtype):
        try:
            return good.astype(dtype) if np.dtype(dtype).kind in "iuf" else np.ones(shape, dtype)
        except (TypeError, ValueError):
            return np.ones(shape)

    return st.one_of(
        wrong_shapes,
        dtypes.map(typed),
        st.tuples(special, st.integers(0, 10**6)).map(poisoned),
        st.just(np.array([None] * n, dtype=object)),
        st.just(np.full(shape, 1e300, dtype=np.longdouble) * 1e300),
        st.just(good[::-1].copy()),
        st.just(np.zeros(shape)),
        st.just(good * 100.0),
        st.just(good / 100.0),
    )


@st.composite
def npz_archives(draw) -> bytes:
    """A valid archive with zero to three faults, sometimes with damaged bytes too."""
    n = draw(st.integers(2, 30), label="n")
    arrays = {
        "time_s": np.arange(1, n + 1) / 10.0,
        "dtheta_rad": np.full((n, 3), 1e-5),
        "dv_mps": np.tile([0.0, 0.0, 0.98], (n, 1)),
        "meta": np.array(GOOD_META),
    }
    if draw(st.booleans(), label="gimbal"):
        arrays["gimbal_deg"] = np.zeros((n, 3))
    for _ in range(draw(st.integers(0, 3), label="faults")):
        name = draw(
            st.sampled_from(["time_s", "dtheta_rad", "dv_mps", "gimbal_deg", "meta", "extra"]), label="array"
        )
        action = draw(st.sampled_from(["replace", "replace", "replace", "drop"]), label="action")
        if action == "drop":
            arrays.pop(name, None)
        elif name == "meta":
            arrays["meta"] = draw(_meta_arrays(), label="meta")
        elif name == "extra":
            arrays[draw(st.text("abcxyz_", min_size=1, max_size=6), label="name")] = np.ones(3)
        else:
            arrays[name] = draw(_bad_array(n, None if name == "time_s" else 3), label=name)
    data = _npz(arrays)
    if draw(st.integers(0, 5), label="damage") == 0:
        data = mutate_bytes(draw(st.data()), data)
    return data


@budget(800)
@given(data=npz_archives())
def test_npz_archives(data, work):
    fuzz_case("npz", work, data)


def _zip_with(members: dict[str, bytes], compression=zipfile.ZIP_STORED) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=compression) as z:
        for name, content in members.items():
            z.writestr(name, content)
    return buffer.getvalue()


def _npy(array) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def _patch_all(data: bytes, old: bytes, new: bytes) -> bytes:
    assert old in data
    return data.replace(old, new)


def _fixed_npz_cases(base: bytes) -> dict[str, bytes]:
    """Damaged archives that random flips rarely produce."""
    z = zipfile.ZipFile(io.BytesIO(base))
    members = {info.filename: z.read(info) for info in z.infolist()}
    time = members["time_s.npy"]
    # time_s.npy claiming 1e12 samples (8 TB) in an archive of a few kB.
    header_len = int.from_bytes(time[8:10], "little")
    header = time[10 : 10 + header_len].decode("latin-1")
    big = header.replace("(40,)", "(1000000000000,)")
    big_npy = (
        time[:8]
        + len(big.ljust(header_len)).to_bytes(2, "little")
        + big.ljust(header_len).encode("latin-1")
        + time[10 + header_len :]
    )
    stored = _zip_with(members)

    def with_header(text: bytes) -> bytes:
        """time_s.npy with another header (padded to the original length)."""
        padded = text.ljust(header_len - 1) + b"\n"
        return _zip_with(
            {
                **members,
                "time_s.npy": time[:8] + len(padded).to_bytes(2, "little") + padded + time[10 + header_len :],
            }
        )

    deflated = _zip_with(members, zipfile.ZIP_DEFLATED)

    # Local and central headers carry the method (offset 8 / 10) and flags (6 / 8).
    def patch_method(data: bytes, method: int) -> bytes:
        out = bytearray(data)
        for sig, off in ((b"PK\x03\x04", 8), (b"PK\x01\x02", 10)):
            for m in re.finditer(re.escape(sig), data):
                out[m.start() + off : m.start() + off + 2] = method.to_bytes(2, "little")
        return bytes(out)

    def patch_flags(data: bytes, flags: int) -> bytes:
        out = bytearray(data)
        for sig, off in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):
            for m in re.finditer(re.escape(sig), data):
                out[m.start() + off : m.start() + off + 2] = flags.to_bytes(2, "little")
        return bytes(out)

    cases = {
        "empty": b"",
        "npy not npz": _npy(np.ones(3)),
        "pickle": b"\x80\x04\x95" + b"\x00" * 20,
        "text": b"# format: imu-run/1\n",
        "truncated central directory": stored[:-10],
        "truncated half": stored[: len(stored) // 2],
        "deflated truncated": deflated[: len(deflated) - 200],
        "unknown compression": patch_method(stored, 99),
        "lzma garbage": patch_method(stored, 14),
        "lzma corrupt stream": patch_method(
            _zip_with({**members, "time_s.npy": b"\x09\x04\x05\x00\x5d\x00\x00\x80\x00" + b"\xff" * 40}), 14
        ),
        "bzip2 garbage": patch_method(stored, 12),
        "deflate garbage": patch_method(stored, 8),
        "encrypted flag": patch_flags(stored, 1),
        "utf-8 names flag": patch_flags(stored, 0x800),
        "huge declared shape": _zip_with({**members, "time_s.npy": big_npy}),
        "object array": _zip_with({**members, "meta.npy": _npy(np.array([{"a": 1}], dtype=object))}),
        "member not npy": _zip_with({**members, "dv_mps.npy": b"hello"}),
        "member empty": _zip_with({**members, "dv_mps.npy": b""}),
        "member bad header": _zip_with({**members, "dv_mps.npy": time[:10] + b"{'descr': <f8" + time[23:]}),
        "member truncated": _zip_with({**members, "dv_mps.npy": members["dv_mps.npy"][:-7]}),
        "member fortran": _zip_with({**members, "dv_mps.npy": _npy(np.asfortranarray(np.ones((40, 3))))}),
        "nested zip": _zip_with({"time_s.npy": stored}),
        "header unbalanced": with_header(header.encode().replace(b"{", b"z", 1)),
        "header unhashable key": with_header(
            b"{[]: 1, 'descr': '<f8', 'fortran_order': False, 'shape': (40,)}"
        ),
        "header not a dict": with_header(b"(" * 100 + b")" * 100),
        "header negative shape": with_header(b"{'descr': '<f8', 'fortran_order': False, 'shape': (-40,)}"),
        "header huge dtype": with_header(
            b"{'descr': '<V99999999999', 'fortran_order': False, 'shape': (40,)}"
        ),
        "header object dtype": with_header(b"{'descr': '|O', 'fortran_order': False, 'shape': (40,)}"),
        "no members": _zip_with({}),
        "duplicate member": _zip_with({**members, "time_s.npy ": members["time_s.npy"]}).replace(
            b"time_s.npy ", b"time_s.npy\x00"
        ),
    }
    return cases


@budget(400)
@given(data=st.data())
def test_npz_member_headers(data, bases, work):
    """Damaged .npy headers inside an intact zip (valid CRCs), so numpy parses them."""
    with zipfile.ZipFile(io.BytesIO(bases["npz"])) as z:
        members = {info.filename: z.read(info) for info in z.infolist()}
    name = data.draw(st.sampled_from(sorted(members)), label="member")
    npy = members[name]
    end = 10 + int.from_bytes(npy[8:10], "little")
    cut = data.draw(st.sampled_from([end, end, 10, 8, 6]), label="header part")
    members[name] = mutate_bytes(data, npy[:cut]) + npy[cut:]
    fuzz_case("npz", work, _zip_with(members))


def test_npz_damaged_archives(bases, work):
    for _name, data in _fixed_npz_cases(bases["npz"]).items():
        fuzz_case("npz", work, data)
