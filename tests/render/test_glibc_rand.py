"""glibc rand() from seed 1, exactly (SPEC B.5)."""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest

from a5mi.render.glibc_rand import GlibcRand, glibc_jitter, jitter_offsets

# rand() with glibc's default seed (no srand): the well-known first ten values.
FIRST_TEN = [1804289383, 846930886, 1681692777, 1714636915, 1957747793,
             424238335, 719885386, 1649760492, 596516649, 1189641421]


def test_b5_first_values() -> None:
    assert GlibcRand().next(10).tolist() == FIRST_TEN


def test_b5_stream_continues_across_calls_and_blocks() -> None:
    """Chunked draws (odd sizes, crossing block boundaries) equal one long draw."""
    whole = GlibcRand(block=64).next(1000)
    g = GlibcRand(block=64)
    parts = np.concatenate([g.next(n) for n in (1, 63, 64, 0, 200, 672)])
    np.testing.assert_array_equal(parts, whole)
    np.testing.assert_array_equal(GlibcRand().next(1000), whole)  # block size does not matter


def test_b5_python_reference_recurrence() -> None:
    """The vectorised generator against a direct loop of r[i] = r[i-3] + r[i-31] (module docstring)."""
    r = [1]
    for i in range(1, 31):
        r.append((16807 * r[i - 1]) % 2147483647)
    r += [r[i - 31] for i in range(31, 34)]
    for i in range(34, 344 + 5000):
        r.append((r[i - 3] + r[i - 31]) & 0xFFFFFFFF)
    expected = [v >> 1 for v in r[344:]]
    assert GlibcRand().next(5000).tolist() == expected


def test_b5_values_in_range() -> None:
    v = GlibcRand().next(100_000)
    assert v.dtype == np.uint32 and v.max() < 2**31


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
def test_b5_matches_compiled_glibc(tmp_path) -> None:
    """100,000 values from a real glibc rand() (compiled C program) equal ours."""
    src = tmp_path / "r.c"
    src.write_text('#include <stdio.h>\n#include <stdlib.h>\n'
                   'int main(void){for(int i=0;i<100000;i++)printf("%d\\n",rand());return 0;}\n')
    exe = tmp_path / "r"
    subprocess.run(["gcc", "-O1", str(src), "-o", str(exe)], check=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    ref = np.array(out.split(), dtype=np.int64)
    np.testing.assert_array_equal(GlibcRand().next(100_000).astype(np.int64), ref)


def test_b5_jitter_offsets_float32() -> None:
    """jitter = (float)r * 2^-31 - 0.5: int->float32 rounding first (2^31-1 -> 2^31 -> +0.5)."""
    v = np.array([0, 2**30, 2**31 - 1, 1804289383], dtype=np.uint32)
    j = jitter_offsets(v)
    assert j.dtype == np.float32
    assert j.tolist()[:3] == [-0.5, 0.0, 0.5]
    assert j[3] == np.float32(np.float32(1804289383) * np.float32(2.0**-31) - np.float32(0.5))


def test_b5_first_call_is_y() -> None:
    """Per sample r1 = rand() gives jy, r2 = rand() gives jx."""
    jx, jy = glibc_jitter(5)
    v = GlibcRand().next(10)
    np.testing.assert_array_equal(jy, jitter_offsets(v[0::2]))
    np.testing.assert_array_equal(jx, jitter_offsets(v[1::2]))
    g = GlibcRand()
    a = glibc_jitter(2, g)
    b = glibc_jitter(3, g)
    np.testing.assert_array_equal(np.concatenate([a[0], b[0]]), jx)


# ---------------------------------------------------------------------------------- on-disk prefix cache


def test_b5_cached_stream_equals_computed_stream_across_the_prefix_end(tmp_path, monkeypatch) -> None:
    """The cached prefix and the computed continuation after it give exactly glibc's stream."""
    from a5mi.render import glibc_rand as g

    monkeypatch.setattr(g, "PREFIX_VALUES", 3 * 4096)
    built = g.glibc_stream(folder=tmp_path)  # computes and stores the prefix
    loaded = g.glibc_stream(folder=tmp_path)  # memory-maps it
    assert isinstance(loaded, g.CachedStream) and loaded._prefix.__class__ is np.memmap
    want = g.GlibcRand().next(3 * 4096 + 5000)
    for stream in (built, loaded):
        got = np.concatenate([stream.next(7), stream.next(3 * 4096 - 10), stream.next(5003)])
        assert np.array_equal(got, want)
    assert np.array_equal(g.first_values(10), want[:10])


@pytest.mark.parametrize("damage", ["value_in_head", "value_past_head", "state", "empty_values", "empty_state",
                                    "truncated_values", "garbage_state", "fifo_values", "fifo_state",
                                    "device_values"])
def test_b5_damaged_cache_is_rejected_and_rebuilt(tmp_path, monkeypatch, damage) -> None:
    """Any damage to the cache files is caught on load (CRC-32s of values and state, fresh head values,
    shapes); the stream is then rebuilt and still exactly glibc's."""
    from a5mi.render import glibc_rand as g

    monkeypatch.setattr(g, "PREFIX_VALUES", 2 * 4096)
    monkeypatch.setattr(g, "_CHECK_VALUES", 100)
    g.glibc_stream(folder=tmp_path)
    values_path, state_path = g._prefix_paths(tmp_path, 1)
    assert g._load_prefix(tmp_path, 1) is not None
    if damage in ("value_in_head", "value_past_head"):
        v = np.load(values_path)
        v[50 if damage == "value_in_head" else 5000] ^= 1
        np.save(values_path, v)
    elif damage == "state":
        m = np.load(state_path)
        m[0] ^= 1
        np.save(state_path, m)
    elif damage == "empty_values":
        values_path.write_bytes(b"")
    elif damage == "empty_state":
        state_path.write_bytes(b"")
    elif damage == "truncated_values":
        values_path.write_bytes(values_path.read_bytes()[:1000])
    elif damage in ("fifo_values", "fifo_state"):  # a FIFO would block np.load forever
        path = values_path if damage == "fifo_values" else state_path
        path.unlink()
        os.mkfifo(path)
    elif damage == "device_values":  # ... and /dev/zero would be read without end
        values_path.unlink()
        values_path.symlink_to("/dev/zero")
    else:
        state_path.write_bytes(b"\x93NUMPY garbage")
    assert g._load_prefix(tmp_path, 1) is None
    want = g.GlibcRand().next(2 * 4096 + 3000)
    assert np.array_equal(g.glibc_stream(folder=tmp_path).next(2 * 4096 + 3000), want)  # rebuilt ...
    assert g._load_prefix(tmp_path, 1) is not None  # ... and stored again


def test_b5_small_draws_and_unwritable_cache_compute_the_stream(tmp_path) -> None:
    from a5mi.render import glibc_rand as g

    assert isinstance(g.glibc_stream(folder=tmp_path, need=100), g.GlibcRand)
    assert list(tmp_path.iterdir()) == []  # a small render never touches the cache
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    want = g.GlibcRand().next(5000)
    assert np.array_equal(g.glibc_stream(folder=blocker / "cache").next(5000), want)
